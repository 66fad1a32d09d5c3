"""Peaks in one TCSPC histogram: background estimate, significance, and the peaks that pass it.

The one peak finder of FLISS. It serves the host's analysis of captures (:mod:`fliss.host.analysis`,
which gives the conventions: positions at code centres, smoothing, background clipping) and the
models' studies (:mod:`fliss.sim.studies.detection` judges its peaks against a scene's truth).
It takes counts per code and a bin width, nothing of a board or a simulation.

Significance
------------
A maximum of the smoothed histogram is a peak when the raw counts of the :func:`window_bins`
codes centred on it are more than the background alone gives with probability
``false_alarm / (N - W + 1)``: Poisson counts of mean ``W b`` (``b`` the background per code),
the tail worked out exactly (:func:`poisson_tail`, :func:`least_count`). Over the ``N - W + 1``
windows of a histogram of ``N`` codes the chance that background alone makes a peak is then at
most ``false_alarm`` (the union bound): :data:`FALSE_ALARM`, one histogram in a thousand, by
default. The same test, with the same function, serves every readout: histograms, raw events
binned, the imager's per-pixel histograms, and the depth engine's threshold
(:mod:`fliss.host.imager.threshold`).
"""

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from ..hdl.event import TDC_LSB_S


__all__ = ["FWHM_PER_SIGMA", "FALSE_ALARM", "Peak", "check_histogram", "smooth", "noise_sigma",
           "background", "smoothed_background", "threshold_height", "find_peaks", "local_maxima",
           "measure_peak", "poisson_tail", "least_count", "window_bins", "significant_count",
           "detection_height"]


#: FWHM of a Gaussian in units of its standard deviation.
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))

#: Probability that background alone makes a peak somewhere in one histogram
#: (:func:`find_peaks`).
FALSE_ALARM = 1e-3


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


def check_histogram(histogram):
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
    histogram = check_histogram(histogram)
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
    histogram = check_histogram(histogram)
    return smoothed_background(histogram, smooth(histogram, sigma_bins), sigma_bins, clip_sigma,
                               guard_bins, iterations)


def smoothed_background(histogram, smoothed, sigma_bins, clip_sigma=4.0, guard_bins=100,
                        iterations=20):
    """The background of :func:`background` from ``smoothed``, the histogram already smoothed."""
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


def measure_peak(smoothed, index, level, sigma_bins, bin_s):
    """The :class:`Peak` at code ``index`` of ``smoothed`` above the background ``level``."""
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
               false_alarm: float = FALSE_ALARM, min_separation_s: float = 5e-9,
               level: float | None = None) -> list[Peak]:
    """Peaks of a histogram, highest first.

    A peak is a maximum of the smoothed histogram above the background whose
    :func:`window_bins` codes (centred on it) hold at least :func:`significant_count` counts
    (background alone, Poisson of mean ``level`` per code, estimated by
    :func:`smoothed_background` unless given, makes such a peak anywhere in the histogram with
    probability at most ``false_alarm``), and the highest of those within ``min_separation_s``
    either side.

    Returns
    -------
    list of Peak
    """
    histogram = check_histogram(histogram)
    smoothed = smooth(histogram, sigma_bins)
    if level is None:
        level = smoothed_background(histogram, smoothed, sigma_bins)
    width = window_bins(sigma_bins, len(histogram))
    needed = significant_count(level, width, len(histogram), false_alarm)
    # The maxima of the smoothed histogram whose windows hold enough counts, then the highest
    # within the separation of each other.
    inner = smoothed[1:-1]
    maxima = np.flatnonzero((inner >= smoothed[:-2]) & (inner > smoothed[2:])) + 1
    first = np.clip(maxima - width // 2, 0, len(histogram) - width)
    sums = np.concatenate(([0.0], np.cumsum(histogram)))
    significant = maxima[sums[first + width] - sums[first] >= needed]
    chosen = local_maxima(smoothed, level, max(1, int(round(min_separation_s / bin_s))),
                          among=significant)
    return [measure_peak(smoothed, index, level, sigma_bins, bin_s) for index in chosen]


def window_bins(sigma_bins: float, bins: int) -> int:
    """Codes of the window whose counts judge a peak: an odd number near the FWHM of the
    smoothing kernel of ``sigma_bins``, at least 1 and at most ``bins``."""
    return max(1, min(2 * int(round(FWHM_PER_SIGMA * sigma_bins / 2)) + 1, bins))


def poisson_tail(mean: float, count: int) -> float:
    """``P(X >= count)`` for ``X`` Poisson of ``mean``, summed exactly (no normal
    approximation)."""
    if count <= 0:
        return 1.0
    if mean <= 0:
        return 0.0
    # The tail from its largest terms: below the mode sum the head and take it from 1.
    if count <= mean:
        term, head = math.exp(-mean), 0.0
        for j in range(count):
            head += term
            term *= mean / (j + 1)
        return max(0.0, 1.0 - head)
    term = math.exp(count * math.log(mean) - mean - math.lgamma(count + 1))
    total, j = 0.0, count
    while term > total * 1e-17:
        total += term
        j += 1
        term *= mean / j
    return min(total, 1.0)


def least_count(mean: float, probability: float, *, most: int | None = None) -> int:
    """The least count ``k`` that Poisson counts of ``mean`` reach (``P(X >= k)``) with
    probability at most ``probability``; at most ``most`` when given."""
    if not 0 < probability <= 1:
        raise ValueError(f"A false-alarm probability must be in (0, 1], not {probability!r}")
    # The tail falls as the count rises: bisect between a count it is above and one it is not.
    low, high = -1, max(1, int(mean) + 1)
    while poisson_tail(mean, high) > probability:
        low, high = high, 2 * high
        if most is not None and high >= most:
            if poisson_tail(mean, most) > probability:
                return most
            high = most
    while high - low > 1:
        middle = (low + high) // 2
        if poisson_tail(mean, middle) > probability:
            low = middle
        else:
            high = middle
    return high


def significant_count(level: float, width: int, bins: int,
                      false_alarm: float = FALSE_ALARM) -> int:
    """The least count of a window of ``width`` codes that background of ``level`` per code
    reaches in any of the ``bins - width + 1`` windows of a histogram with probability at most
    ``false_alarm`` (at least 1: an empty window is never a peak)."""
    windows = max(bins - width + 1, 1)
    return max(1, least_count(max(level, 0.0) * width, false_alarm / windows))


def detection_height(level: float, sigma_bins: float, bins: int,
                     false_alarm: float = FALSE_ALARM) -> float:
    """The height above the background, in counts per code, of the least peak that passes
    :func:`find_peaks`'s test: the significant count of a window, less its background, per
    code of the window."""
    width = window_bins(sigma_bins, bins)
    return (significant_count(level, width, bins, false_alarm) - max(level, 0.0) * width) / width


def local_maxima(smoothed, threshold, separation, among=None):
    """Codes of the maxima of ``smoothed`` above ``threshold`` (of the codes ``among`` when
    given), highest first, each the highest within ``separation`` codes of the ones before
    it."""
    if among is None:
        inner = smoothed[1:-1]
        maxima = np.flatnonzero((inner >= smoothed[:-2]) & (inner > smoothed[2:]) &
                                (inner > threshold)) + 1
    else:
        maxima = np.asarray(among, dtype=np.int64)
        maxima = maxima[smoothed[maxima] > threshold]
    chosen = []
    for index in maxima[np.argsort(smoothed[maxima], kind="stable")[::-1]]:
        if all(abs(index - other) > separation for other in chosen):
            chosen.append(index)
    return chosen


def threshold_height(level, sigma_bins=5.0, threshold_sigma=5.0):
    """Height above the background of the detection studies' threshold
    (:mod:`fliss.sim.studies.detection` scores peaks in noise deviations): ``threshold_sigma``
    deviations of the smoothed histogram (:func:`noise_sigma`), but at least one count per
    code. :func:`find_peaks` judges peaks by :func:`significant_count` instead."""
    return max(threshold_sigma * noise_sigma(level, sigma_bins), 1.0)
