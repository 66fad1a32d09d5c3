"""Bit-exact model of :class:`fliss.hdl.depth.DepthEngine`: depth frames from per-pixel
histograms, and the DEPTH payload.

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
from amaranth.lib import data

from ..hdl.event import TIMESTAMP_BITS
from ..hdl.histogram import COUNT_WIDTH, MAX_SHIFT
from ..hdl.protocol import (DepthHeader, DepthRecord, DEPTH_HEADER_BYTES, DEPTH_RECORD_BYTES,
                            DEPTH_PIXELS, DEPTH_FRACTION_BITS, DEPTH_BACKGROUND_FRACTION_BITS)
from ..hdl.registers import DEPTH
from .codec import pack, unpack_from


__all__ = ["RECORD_DTYPE", "BACKGROUND_MAX", "check_depth_settings", "depth_frame",
           "depth_payload", "unpack_depth"]


#: The fields of a :class:`~fliss.hdl.protocol.DepthRecord`, as the engine makes them.
RECORD_DTYPE = np.dtype([("position", np.int64), ("detected", np.bool_),
                         ("height", np.int64), ("background", np.int64)])

#: Largest ``background`` (it saturates there).
BACKGROUND_MAX = (1 << data.Layout.cast(DepthRecord)["background"].width) - 1

_FILTER = DEPTH.register("filter")
_THRESHOLD = DEPTH.register("threshold")
_ONE = 1 << DEPTH_FRACTION_BITS
_BACKGROUND_ONE = 1 << DEPTH_BACKGROUND_FRACTION_BITS


def check_depth_settings(*, shift, filter, threshold, pixel_bits=0, first_pixel=0):
    """Raise :exc:`ValueError` with one clear line unless the depth settings are valid."""
    for name, value, low, high in (("Bin shift", shift, 0, MAX_SHIFT),
                                   ("Depth filter", filter, _FILTER.minimum, _FILTER.maximum),
                                   ("Depth threshold", threshold, _THRESHOLD.minimum,
                                    _THRESHOLD.maximum),
                                   ("Pixel bits", pixel_bits, 0, 6),
                                   ("First pixel", first_pixel, 0, DEPTH_PIXELS - 1)):
        if not isinstance(value, (int, np.integer)) or not low <= value <= high:
            raise ValueError(f"{name} must be an integer from {low} to {high}, not {value!r}")
    if first_pixel + (1 << pixel_bits) > DEPTH_PIXELS:
        raise ValueError(f"First pixel {first_pixel} plus {1 << pixel_bits} pixels is beyond "
                         f"the {DEPTH_PIXELS} pixels of a frame")


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


def depth_payload(records, *, frame, first_pixel, pixel_bits, shift, filter, threshold):
    """The payload of the DEPTH packet of one frame: its :class:`DepthHeader` and ``records``
    (:data:`RECORD_DTYPE`, ``2**pixel_bits`` of them), as the gateware sends it."""
    check_depth_settings(shift=shift, filter=filter, threshold=threshold,
                         pixel_bits=pixel_bits, first_pixel=first_pixel)
    if len(records) != 1 << pixel_bits:
        raise ValueError(f"A frame of 2**{pixel_bits} pixels needs {1 << pixel_bits} records, "
                         f"not {len(records)}")
    head = pack(DepthHeader, frame=frame & 0xffffffff, first_pixel=first_pixel,
                pixel_bits=pixel_bits, shift=shift, filter=filter, threshold=threshold)
    return head + b"".join(
        pack(DepthRecord, position=int(r["position"]), detected=int(r["detected"]),
             height=int(r["height"]), background=int(r["background"])) for r in records)


def unpack_depth(payload):
    """The header (a dict of :class:`DepthHeader` fields) and records (:data:`RECORD_DTYPE`) of
    a DEPTH payload; raises :exc:`ValueError` with one line for a malformed one."""
    payload = bytes(payload)
    if len(payload) < DEPTH_HEADER_BYTES:
        raise ValueError(f"DEPTH payload of {len(payload)} bytes is shorter than its "
                         f"{DEPTH_HEADER_BYTES}-byte header")
    head = unpack_from(DepthHeader, payload)
    if head["pixel_bits"] > 6 or head["shift"] > MAX_SHIFT or \
            head["first_pixel"] + (1 << min(head["pixel_bits"], 6)) > DEPTH_PIXELS:
        raise ValueError(f"DEPTH header out of range: {head['pixel_bits']} pixel bits, first "
                         f"pixel {head['first_pixel']}, bin shift {head['shift']}")
    pixels = 1 << head["pixel_bits"]
    expected = DEPTH_HEADER_BYTES + pixels * DEPTH_RECORD_BYTES
    if len(payload) != expected:
        raise ValueError(f"DEPTH payload of {len(payload)} bytes, not {expected} for "
                         f"{pixels} pixels")
    raw = np.frombuffer(payload, np.uint8, offset=DEPTH_HEADER_BYTES).reshape(
        pixels, DEPTH_RECORD_BYTES)
    words = np.zeros((pixels, 8), np.uint8)
    words[:, :DEPTH_RECORD_BYTES] = raw
    words = words.view("<u8")[:, 0]
    records = np.zeros(pixels, RECORD_DTYPE)
    for name, field in data.Layout.cast(DepthRecord):
        value = (words >> np.uint64(field.offset)) & np.uint64((1 << field.width) - 1)
        records[name] = value.astype(RECORD_DTYPE[name])
    return head, records
