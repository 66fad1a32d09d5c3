"""Code-density calibration of a tapped-delay-line TDC: one description for the models, the
studies and the host.

A fine TDC samples a delay line at a clock edge and counts the taps the hit has passed: its raw
code ``c``. Hits uncorrelated with the clock (a free-running oscillator, ambient light) land
uniformly over a clock period, so the number of hits per code is proportional to the code's
width in time (*code density*). From a histogram of raw codes:

* :func:`code_widths`: each code's width, the counts scaled so that they add up to one period;
* :func:`code_centres`: the time of each code's centre, measured back from the sampling edge
  (the codes below it, plus half its own width);
* :func:`table`: those centres in whole units of a given LSB, the calibration table the gateware
  holds (raw code -> fine time);
* :func:`dnl` and :func:`inl`: differential and integral non-linearity, in units of the mean
  code width.

It takes counts and a clock period, nothing of a board or a simulation.
"""

import numpy as np
from numpy.typing import ArrayLike


__all__ = ["check_counts", "code_widths", "code_centres", "table", "dnl", "inl"]


def check_counts(counts: ArrayLike) -> np.ndarray:
    """``counts`` as a float array, refused unless it is a 1-D histogram of non-negative
    counts with at least one hit."""
    counts = np.asarray(counts)
    if counts.ndim != 1 or len(counts) < 2:
        raise ValueError(f"A code-density histogram must be a 1-D array of at least 2 codes, "
                         f"not of shape {counts.shape}")
    counts = counts.astype(np.float64)
    if not np.all(np.isfinite(counts)) or np.any(counts < 0):
        raise ValueError("A code-density histogram holds non-negative counts")
    if not counts.sum() > 0:
        raise ValueError("A code-density histogram needs at least one hit")
    return counts


def code_widths(counts: ArrayLike, period_s: float) -> np.ndarray:
    """Width of each raw code in seconds: its share of the hits times the clock period."""
    counts = check_counts(counts)
    if not period_s > 0:
        raise ValueError(f"Clock period must be positive, not {period_s!r}")
    return counts / counts.sum() * period_s


def code_centres(counts: ArrayLike, period_s: float) -> np.ndarray:
    """Time of each raw code's centre before the sampling edge, in seconds: the widths of the
    codes below it plus half its own (the constant delay in front of the first tap left out)."""
    widths = code_widths(counts, period_s)
    return np.cumsum(widths) - widths / 2


def table(counts: ArrayLike, period_s: float, lsb_s: float, *, width: int | None = None) -> \
        np.ndarray:
    """The calibration table: each raw code's centre (:func:`code_centres`) in whole LSBs of
    ``lsb_s``, rounded to the nearest (``numpy.int64``). With ``width`` (bits), refused if an
    entry does not fit."""
    if not lsb_s > 0:
        raise ValueError(f"LSB must be positive, not {lsb_s!r}")
    entries = np.rint(code_centres(counts, period_s) / lsb_s).astype(np.int64)
    if width is not None and entries.max() >= 1 << width:
        raise ValueError(f"Calibration entries up to {entries.max()} do not fit {width} bits")
    return entries


def _used(counts):
    # The codes from the first to the last one hit
    counts = check_counts(counts)
    hit = np.flatnonzero(counts)
    return counts[hit[0]:hit[-1] + 1]


def dnl(counts: ArrayLike) -> np.ndarray:
    """Differential non-linearity of each code from the first to the last one hit: its width
    over the mean width, minus one (the edge codes, which a clock period cuts, included)."""
    used = _used(counts)
    return used / used.mean() - 1.0


def inl(counts: ArrayLike) -> np.ndarray:
    """Integral non-linearity at each code's centre, from the first to the last code hit, in
    mean code widths: where the code's centre lies against where equal codes would put it."""
    used = _used(counts)
    mean = used.mean()
    centres = np.cumsum(used) - used / 2
    return centres / mean - (np.arange(len(used)) + 0.5)
