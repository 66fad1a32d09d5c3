"""Analysis of TCSPC histograms: background, peaks, suppression ratio, deviations (section 6).

Every function takes histograms as numpy arrays of counts per TDC code, so the same analysis
serves simulated acquisitions (:func:`fliss.sim.scene.acquire`) and captured ones.

Conventions
-----------
* Code ``b`` covers ``[b, b + 1)`` TDC LSBs from the TDC start; a position is given in seconds at
  the centre of the codes, ``(b + 0.5) * bin_s``.
* Peaks are found and measured on the histogram smoothed by a Gaussian of ``smooth_bins``
  standard deviation (5 codes, 250 ps, by default), which beats down the Poisson noise of single
  codes. The height of a peak is the smoothed count per code above the background at its maximum
  (smoothing lowers a 2.1 ns Gaussian peak by 2 %, the same for victim and aggressor). Its FWHM is
  measured on the smoothed curve, between the half-height crossings interpolated linearly, and the
  kernel's width is removed in quadrature.
* The background is the mean count per code once the peaks (and a guard band around them) are
  clipped out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..hdl.event import TDC_LSB_S
from ..analysis.peaks import (FWHM_PER_SIGMA, Peak, background, find_peaks, noise_sigma,
                              smooth)
from ..analysis.peaks import check_histogram as _check_histogram
from ..analysis.peaks import threshold_height as _threshold


__all__ = ["analyze", "FWHM_PER_SIGMA", "Peak", "Suppression", "background", "smooth", "noise_sigma",
           "find_peaks", "identify", "suppression_db", "suppression", "relative_deviation",
           "mean_std"]


@dataclass(frozen=True)
class Suppression:
    """Suppression ratio of one histogram (equation 10).

    Attributes
    ----------
    s_db : float
        ``10 log10(Pv / Pa)``.
    pv, pa : float
        Heights of the victim's peak and of the highest aggressor peak.
    limited : bool
        No aggressor peak rose above the detection threshold: ``pa`` is that threshold and
        ``s_db`` a lower bound.
    victim : Peak or None
    aggressors : tuple of Peak
    """

    s_db: float
    pv: float
    pa: float
    limited: bool
    victim: Peak | None
    aggressors: tuple[Peak, ...]


def identify(peaks: Sequence[Peak], victim_s: float, aggressors_s: Sequence[float] = (), *,
             tolerance_s: float = 1.5e-9) -> tuple[Peak | None, list[Peak], list[Peak]]:
    """Sort peaks into the victim's, the aggressors' and the others, by reference positions.

    Parameters
    ----------
    peaks : list of Peak
    victim_s : float
        Position of the victim's peak in a reference run without interference.
    aggressors_s : sequence of float
        Positions of the aggressor peaks in a reference run with the victim's laser off.

    Returns
    -------
    (Peak or None, list of Peak, list of Peak)
        The victim's peak (the highest within ``tolerance_s`` of ``victim_s``), the aggressor
        peaks (within ``tolerance_s`` of an aggressor reference), the rest.
    """
    victim = None
    aggressors, others = [], []
    references = np.sort(np.asarray(aggressors_s, dtype=float))
    for peak in sorted(peaks, key=lambda peak: -peak.height):
        if victim is None and abs(peak.position_s - victim_s) <= tolerance_s:
            victim = peak
        elif len(references) and np.min(np.abs(references - peak.position_s)) <= tolerance_s:
            aggressors.append(peak)
        else:
            others.append(peak)
    return victim, aggressors, others


def suppression_db(pv: float, pa: float) -> float:
    """Equation 10: ``S = 10 log10(Pv / Pa)`` in dB."""
    if not pv > 0 or not pa > 0:
        raise ValueError(f"Peak heights must be positive, not Pv={pv!r}, Pa={pa!r}")
    return 10.0 * math.log10(pv / pa)


def suppression(histogram: ArrayLike, victim_s: float, aggressors_s: Sequence[float], *,
                bin_s: float = TDC_LSB_S, sigma_bins: float = 5.0, threshold_sigma: float = 5.0,
                tolerance_s: float = 1.5e-9) -> Suppression:
    """Suppression ratio of one histogram, Pa being the highest aggressor peak.

    The victim's and the aggressors' peaks are told apart by reference positions (see
    :func:`identify`). When no aggressor peak clears the detection threshold, Pa is the
    threshold and the result is marked ``limited`` (a lower bound of S). Raises
    :exc:`ValueError` when the victim's peak is not found.
    """
    histogram = _check_histogram(histogram)
    level = background(histogram, sigma_bins=sigma_bins)
    peaks = find_peaks(histogram, bin_s=bin_s, sigma_bins=sigma_bins,
                       threshold_sigma=threshold_sigma, level=level)
    victim, aggressors, _ = identify(peaks, victim_s, aggressors_s, tolerance_s=tolerance_s)
    if victim is None:
        raise ValueError(f"No victim peak within {tolerance_s * 1e9:g} ns of "
                         f"{victim_s * 1e9:g} ns")
    if aggressors:
        pa, limited = max(peak.height for peak in aggressors), False
    else:
        pa, limited = _threshold(level, sigma_bins, threshold_sigma), True
    return Suppression(suppression_db(victim.height, pa), victim.height, pa, limited, victim,
                       tuple(aggressors))


def relative_deviation(values: ArrayLike, reference: float) -> np.ndarray:
    """``(values - reference) / reference``, element by element (Figure 11)."""
    values = np.asarray(values, dtype=float)
    if reference == 0:
        raise ValueError("The reference value must not be zero")
    return (values - reference) / reference


def mean_std(values: ArrayLike) -> tuple[float, float]:
    """Mean and sample standard deviation (``ddof=1``; 0 for a single value) of the finite
    values."""
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values)]
    if len(values) == 0:
        return math.nan, math.nan
    return float(values.mean()), float(values.std(ddof=1)) if len(values) > 1 else 0.0


def analyze(histogram, bin_s, *, victim_s=None, aggressors_s=(), tolerance_s=1.5e-9,
            aggressor_on=False, shift=0):
    """Background, peaks and (when it can be told) suppression of one histogram.

    Returns ``(level, peaks, suppression or None, note)``."""
    sigma_bins = max(5.0 / (1 << shift), 1.0)
    level = background(histogram, sigma_bins=sigma_bins)
    peaks = find_peaks(histogram, bin_s=bin_s, sigma_bins=sigma_bins, level=level)
    result, note = None, ""
    if victim_s is None and peaks and (aggressor_on or len(peaks) > 1 or aggressors_s):
        victim_s = peaks[0].position_s
        note = "victim = tallest peak"
        if not aggressors_s:
            aggressors_s = [peak.position_s for peak in peaks[1:]]
    if victim_s is not None and peaks and not aggressors_s:
        # Every other peak is an aggressor's: S is against the highest of them (equation 10).
        aggressors_s = [peak.position_s for peak in peaks
                        if abs(peak.position_s - victim_s) > tolerance_s]
    if victim_s is not None and peaks:
        try:
            result = suppression(histogram, victim_s, aggressors_s, bin_s=bin_s,
                                          sigma_bins=sigma_bins, tolerance_s=tolerance_s)
        except ValueError as error:
            note = str(error)
    return level, peaks, result, note
