"""Bit-exact model of :class:`fliss.hdl.depth.engine.DepthEngine`: depth frames from per-pixel
histograms (the DEPTH payload is :mod:`fliss.protocol.depth`).

For each pixel (a row of ``N = 2**(13 - shift)`` bins) the engine finds (``docs/depth.md``):

* the box (matched) filter sums ``f[k] = c[k - W + 1] + … + c[k]`` of the windows that lie inside
  the pixel, ``W = min(filter, N)``, and the first window of the largest sum (``k``, ``F``);
* the background: the mean count per bin outside that window, ``R / D`` with ``R = S - F``
  (``S`` the pixel's total) and ``D = N - W``, in 1/16 count, rounded down, saturating at
  ``2**18 - 1`` (0 when ``D = 0``);
* the height: ``F - W R / D``, rounded down, at least 0 (``F`` when ``D = 0``);
* the position: the window's centre, ``k + 1 - W / 2`` bins, plus the vertex of the parabola
  through the sums of the windows before, at and after it, ``(a - b) / (2 (a + b))`` with
  ``a = F - f[k - 1]``, ``b = F - f[k + 1]`` (0 when the window is the first or last), in 1/16
  bin, rounded toward zero;
* ``detected``: the height reaches ``threshold``.
"""

import numpy as np

from ...hdl.histogram.engine import COUNT_WIDTH
from ...hdl.event import TIMESTAMP_BITS
from ...hdl.protocol import DEPTH_FRACTION_BITS, DEPTH_BACKGROUND_FRACTION_BITS, DEPTH_PIXELS
from ...protocol.depth import BACKGROUND_MAX, RECORD_DTYPE, check_depth_settings


__all__ = ["depth_frame"]


_ONE = 1 << DEPTH_FRACTION_BITS
_BACKGROUND_ONE = 1 << DEPTH_BACKGROUND_FRACTION_BITS


def depth_frame(counts, *, shift, filter, threshold):
    """The depth records of one frame.

    Parameters
    ----------
    counts : array_like, shape (P, N)
        Bin counts of each pixel (0 to ``2**16 - 1``), ``N = 2**(13 - shift)``.
    shift, filter, threshold : int
        The frame's bin shift, the ``depth_filter`` and ``depth_threshold`` registers.

    Returns
    -------
    numpy.ndarray of :data:`RECORD_DTYPE`, shape (P,)
        ``position`` in 1/16 bin, ``detected``, ``height`` in counts, ``background`` in 1/16
        count per bin: the integers of the DEPTH records.
    """
    check_depth_settings(shift=shift, filter=filter, threshold=threshold)
    counts = np.asarray(counts)
    bins = 1 << (TIMESTAMP_BITS - shift)
    if counts.ndim != 2 or counts.shape[1] != bins or not 1 <= counts.shape[0] <= DEPTH_PIXELS:
        raise ValueError(f"Counts must have shape (1 to {DEPTH_PIXELS} pixels, {bins} bins) for "
                         f"bin shift {shift}, not {counts.shape}")
    if not np.issubdtype(counts.dtype, np.integer) or \
            (counts.size and (counts.min() < 0 or counts.max() >= 1 << COUNT_WIDTH)):
        raise ValueError(f"Counts must be from 0 to {(1 << COUNT_WIDTH) - 1}")
    counts = counts.astype(np.int64)
    width = min(filter, bins)
    spare = bins - width
    sums = np.cumsum(counts, axis=1)
    windows = sums[:, width - 1:] - np.pad(sums, ((0, 0), (1, 0)))[:, :bins - width + 1]
    best = np.argmax(windows, axis=1)               # the first of the largest
    rows = np.arange(len(counts))
    peak = windows[rows, best]
    rest = sums[:, -1] - peak
    records = np.zeros(len(counts), RECORD_DTYPE)
    if spare:
        records["background"] = np.minimum(rest * _BACKGROUND_ONE // spare, BACKGROUND_MAX)
        # F - ceil(W R / D)
        records["height"] = np.maximum(peak + (-(width * rest) // spare), 0)
    else:
        records["height"] = peak
    inside = (best > 0) & (best < len(windows[0]) - 1)
    left = windows[rows, np.maximum(best - 1, 0)]
    right = windows[rows, np.minimum(best + 1, len(windows[0]) - 1)]
    a, b = peak - left, peak - right
    step = np.zeros(len(counts), np.int64)
    step[inside] = np.sign(a - b)[inside] * (
        (_ONE // 2) * np.abs(a - b)[inside] // (a + b)[inside])
    end = best + width                               # one past the window's last bin
    records["position"] = _ONE * end - (_ONE // 2) * width + step
    records["detected"] = records["height"] >= threshold
    return records
