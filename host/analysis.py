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
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from ..hdl.event import TDC_LSB_S


__all__ = ["FWHM_PER_SIGMA", "Peak", "Suppression", "background", "smooth", "noise_sigma",
           "find_peaks", "identify", "suppression_db", "suppression", "relative_deviation",
           "mean_std"]


#: FWHM of a Gaussian in units of its standard deviation.
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))


@dataclass(frozen=True)
class Peak:
    """One histogram peak.

    Attributes
    ----------
    index : int
        Code of the maximum of the smoothed histogram.
    position_s : float
        Time of the peak from the TDC start (the ToF for the victim's peak), interpolated.
    fwhm_s : float
        Full width at half maximum.
    height : float
        Counts per code above the background at the maximum.
    """

    index: int
    position_s: float
    fwhm_s: float
    height: float


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


def _check_histogram(histogram):
    histogram = np.asarray(histogram)
    if histogram.ndim != 1 or len(histogram) < 3:
        raise ValueError(f"A histogram must be a 1-D array of at least 3 bins, "
                         f"not of shape {histogram.shape}")
    return histogram.astype(np.float64)


@lru_cache(maxsize=16)
def _kernel(sigma_bins):
    if not sigma_bins > 0:
        raise ValueError(f"Smoothing width must be positive, not {sigma_bins!r}")
    half = int(math.ceil(4 * sigma_bins))
    x = np.arange(-half, half + 1)
    kernel = np.exp(-0.5 * (x / sigma_bins) ** 2)
    return kernel / kernel.sum()


def smooth(histogram: ArrayLike, sigma_bins: float = 5.0) -> np.ndarray:
    """The histogram convolved with a unit-area Gaussian of ``sigma_bins`` (edges: zero padding
    corrected, so a flat histogram stays flat)."""
    histogram = _check_histogram(histogram)
    return np.convolve(histogram, _kernel(sigma_bins), mode="same") / _edge_weight(
        len(histogram), sigma_bins)


@lru_cache(maxsize=16)
def _edge_weight(length, sigma_bins):
    return np.convolve(np.ones(length), _kernel(sigma_bins), mode="same")


def noise_sigma(level: float, sigma_bins: float = 5.0) -> float:
    """Standard deviation of the smoothed histogram where the raw one is Poisson of mean
    ``level`` per code: ``sqrt(level * sum(k**2))``."""
    return math.sqrt(max(level, 0.0) * float(np.sum(_kernel(sigma_bins) ** 2)))


def background(histogram: ArrayLike, *, sigma_bins: float = 5.0, clip_sigma: float = 4.0,
               guard_bins: int = 100, iterations: int = 20) -> float:
    """Background level in counts per code: the mean of the codes left after clipping, again and
    again, whatever the smoothed histogram lifts above ``clip_sigma`` noise deviations (plus
    ``guard_bins`` codes either side)."""
    histogram = _check_histogram(histogram)
    return _background(histogram, smooth(histogram, sigma_bins), sigma_bins, clip_sigma,
                       guard_bins, iterations)


def _background(histogram, smoothed, sigma_bins, clip_sigma=4.0, guard_bins=100, iterations=20):
    keep = np.ones(len(histogram), dtype=bool)
    level = histogram.mean()
    for _ in range(iterations):
        threshold = level + clip_sigma * max(noise_sigma(level, sigma_bins), 1e-12)
        # Codes within guard_bins of a high code are left out (a running sum dilates the mask)
        high = np.concatenate(([0], np.cumsum(smoothed > threshold)))
        lo = np.maximum(np.arange(len(histogram)) - guard_bins, 0)
        hi = np.minimum(np.arange(len(histogram)) + guard_bins + 1, len(histogram))
        new_keep = high[hi] == high[lo]
        if not new_keep.any():
            break
        new_level = histogram[new_keep].mean()
        if np.array_equal(new_keep, keep):
            level = new_level
            break
        keep, level = new_keep, new_level
    return float(level)


def _measure(smoothed, index, level, sigma_bins, bin_s):
    height = smoothed[index] - level
    # Position: parabola through the maximum and its neighbours
    offset = 0.0
    if 0 < index < len(smoothed) - 1:
        left, centre, right = smoothed[index - 1:index + 2]
        curvature = left - 2 * centre + right
        if curvature < 0:
            offset = float(np.clip(0.5 * (left - right) / curvature, -0.5, 0.5))
    half = level + height / 2

    def crossing(step):
        i = index
        while 0 <= i + step < len(smoothed) and smoothed[i + step] > half:
            i += step
        if not 0 <= i + step < len(smoothed):
            return float(i)
        outer, inner = smoothed[i + step], smoothed[i]
        return i + step * (inner - half) / (inner - outer)

    width = crossing(+1) - crossing(-1)
    width = math.sqrt(max(width ** 2 - (FWHM_PER_SIGMA * sigma_bins) ** 2, 0.0))
    return Peak(index=int(index), position_s=(index + offset + 0.5) * bin_s,
                fwhm_s=width * bin_s, height=float(height))


def find_peaks(histogram: ArrayLike, *, bin_s: float = TDC_LSB_S, sigma_bins: float = 5.0,
               threshold_sigma: float = 5.0, min_separation_s: float = 5e-9,
               level: float | None = None) -> list[Peak]:
    """Peaks of a histogram, highest first.

    A peak is a maximum of the smoothed histogram at least ``threshold_sigma`` noise deviations
    above the background (:func:`noise_sigma` of the background level, but at least one count)
    and the highest within ``min_separation_s`` either side.

    Returns
    -------
    list of Peak
    """
    histogram = _check_histogram(histogram)
    smoothed = smooth(histogram, sigma_bins)
    if level is None:
        level = _background(histogram, smoothed, sigma_bins)
    threshold = level + _threshold(level, sigma_bins, threshold_sigma)
    inner = smoothed[1:-1]
    maxima = np.flatnonzero((inner >= smoothed[:-2]) & (inner > smoothed[2:]) &
                            (inner > threshold)) + 1
    separation = max(1, int(round(min_separation_s / bin_s)))
    chosen = []
    for index in maxima[np.argsort(smoothed[maxima], kind="stable")[::-1]]:
        if all(abs(index - other) > separation for other in chosen):
            chosen.append(index)
    return [_measure(smoothed, index, level, sigma_bins, bin_s) for index in chosen]


def _threshold(level, sigma_bins, threshold_sigma):
    return max(threshold_sigma * noise_sigma(level, sigma_bins), 1.0)


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
