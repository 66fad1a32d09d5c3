"""The depth threshold that suits a pixel split: the height that background alone seldom reaches.

The depth engine (``docs/depth.md``) calls a pixel's strongest window of ``W`` bins detected when
its height above the background, ``h = F - W b``, reaches ``depth_threshold``. Background alone
makes windows of Poisson counts of mean ``mu = W b``, and the engine keeps the largest of a
pixel's ``N - W + 1`` windows (about ``N / W`` independent ones), so a threshold that suits one
split is far off for another: 16 counts suits 8192 bins of one pixel, and detects nothing in
64 pixels of 1024 bins, whose windows hold a tenth as many counts.

The background a pixel can have is bounded by the sensor: the paper's column has one TDC, which
keeps at most one photon per laser cycle for all its pixels, and a frame holds at most
``n = integration / period`` laser cycles. Spread evenly over ``P`` pixels of ``N`` bins that is
``b = n / (P N)`` counts per bin, the background of a column that fires every cycle (as it does
in bright ambient light, where the background is flattest). :func:`depth_threshold` is the least
height that background reaches in at most :data:`FALSE_DETECTIONS` of a pixel's frames there,
worked out by the Poisson tail of the peak finder's significance test
(:func:`fliss.analysis.peaks.least_count`).
"""

import math
from typing import Mapping

from ...analysis.peaks import least_count
from ...hdl.event import TIMESTAMP_BITS


__all__ = ["FALSE_DETECTIONS", "depth_threshold", "nothing_detected"]


#: Fraction of a pixel's frames in which background alone may reach the threshold.
FALSE_DETECTIONS = 0.01

#: The ``depth_threshold`` register's range.
_MAX_THRESHOLD = (1 << 16) - 1


def depth_threshold(registers: Mapping[str, int]) -> int:
    """The least ``depth_threshold`` (counts) at which the background of a column that fires
    every laser cycle is detected in at most :data:`FALSE_DETECTIONS` of a pixel's frames, for
    the split, filter, integration time and period of ``registers``."""
    bins = (1 << TIMESTAMP_BITS) >> registers["bin_shift"]
    pixels = 1 << registers["pixel_bits"]
    width = min(registers["depth_filter"], bins)
    cycles = registers["integration"] / registers["period"]
    mean = width * cycles / (pixels * bins)             # mu = W b
    windows = max(bins / width, 1.0)
    # The least count k that one of `windows` windows of Poisson(mean) reaches so seldom (the
    # peak finder's test, fliss.analysis.peaks.least_count); the height is k less the
    # background the engine subtracts.
    count = least_count(mean, FALSE_DETECTIONS / windows, most=_MAX_THRESHOLD + 1)
    return max(1, min(_MAX_THRESHOLD, math.ceil(count - mean)))


def nothing_detected(frames: int, highest: int, threshold: int, *, style: str = "flag") -> str:
    """One line for depth frames in which no pixel detected a target: how near the strongest
    peak came (``highest``, counts above background) to ``threshold``, and what to try; the
    settings named as flags (``style="flag"``) or keywords."""
    def name(setting):
        return f"--{setting.replace('_', '-')}" if style == "flag" else setting
    return (f"no pixel detected a target in {frames} depth frame{'s' * (frames != 1)}: the "
            f"highest peak was {highest} counts above the background, {name('depth_threshold')}"
            f" is {threshold}; try a longer {name('integration')} (more photons), a larger "
            f"{name('depth_filter')} or {name('bin_shift')} (a wider window), or a lower "
            f"{name('depth_threshold')} (more false detections)")
