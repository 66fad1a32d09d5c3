"""Target detection in one TCSPC histogram, and the decision metrics of many frames.

The detector (background estimate, threshold, peaks above it) serves the host's analysis
(:mod:`fliss.host.analysis`) and the interference study (:mod:`fliss.sim.studies.interference`); see the
host module for the conventions (positions at code centres, smoothing, background clipping).

Per frame (one acquisition), with the true time of flight known (:func:`classify`):

* **miss**: no detection within ``window_fwhm`` (3) FWHM of the true time of flight;
* **ghost**: a detection anywhere else;
* **wrong depth**: a detection exists and the strongest one is not the true target;
* **depth error**: distance of the strongest detection within the window from the truth.

Over frames: proportions with Wilson score intervals (:func:`wilson`), and the detection curve
(:func:`detection_curve`): P(detect) against false targets per frame as the threshold varies.
"""

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from ...hdl.event import TDC_LSB_S
from ..scene.description import SPEED_OF_LIGHT


__all__ = ["FWHM_PER_SIGMA", "Peak", "check_histogram", "smooth", "noise_sigma", "background",
           "threshold_height", "find_peaks", "Frame", "classify", "wilson", "detection_curve"]


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
    histogram = check_histogram(histogram)
    smoothed = smooth(histogram, sigma_bins)
    if level is None:
        level = _background(histogram, smoothed, sigma_bins)
    chosen = _maxima(smoothed, level + threshold_height(level, sigma_bins, threshold_sigma),
                     max(1, int(round(min_separation_s / bin_s))))
    return [_measure(smoothed, index, level, sigma_bins, bin_s) for index in chosen]


def _maxima(smoothed, threshold, separation):
    """Codes of the maxima of ``smoothed`` above ``threshold``, highest first, each the highest
    within ``separation`` codes of the ones before it."""
    inner = smoothed[1:-1]
    maxima = np.flatnonzero((inner >= smoothed[:-2]) & (inner > smoothed[2:]) &
                            (inner > threshold)) + 1
    chosen = []
    for index in maxima[np.argsort(smoothed[maxima], kind="stable")[::-1]]:
        if all(abs(index - other) > separation for other in chosen):
            chosen.append(index)
    return chosen


def threshold_height(level, sigma_bins=5.0, threshold_sigma=5.0):
    """Height above the background a peak must exceed: ``threshold_sigma`` noise deviations of
    the smoothed histogram (:func:`noise_sigma`), but at least one count per code."""
    return max(threshold_sigma * noise_sigma(level, sigma_bins), 1.0)


@dataclass(frozen=True)
class Frame:
    """What the detector made of one frame (see :func:`classify`).

    Attributes
    ----------
    miss, ghost, wrong_depth : bool
    depth_error_m : float
        Position of the strongest detection within the window minus the truth, as a distance
        (``c t / 2``); NaN on a miss.
    target_height, other_height : float
        Highest smoothed count per code above the background within the window, and outside it
        (whether or not above the threshold): the S of the frame is their ratio.
    target_score : float
        Largest threshold (noise deviations) at which the target is still detected; 0 if never.
    other_scores : numpy.ndarray
        The same for every peak outside the window (those above the curve's floor).
    """

    miss: bool
    ghost: bool
    wrong_depth: bool
    depth_error_m: float
    target_height: float
    other_height: float
    target_score: float
    other_scores: np.ndarray


def classify(histogram: ArrayLike, tof_s: float, fwhm_s: float, *, threshold_sigma: float = 5.0,
             window_fwhm: float = 3.0, floor_sigma: float | None = None, bin_s: float = TDC_LSB_S,
             sigma_bins: float = 5.0, min_separation_s: float = 5e-9) -> Frame:
    """Detect targets in one histogram and judge them against the true time of flight.

    Parameters
    ----------
    histogram : array_like
        Counts per TDC code.
    tof_s : float
        True time of flight (position of the true target from the TDC start).
    fwhm_s : float
        FWHM of the target's peak; the true target is any detection within ``window_fwhm`` FWHM
        of ``tof_s``.
    threshold_sigma : float
        Detection threshold, as :func:`find_peaks` takes it.
    floor_sigma : float or None
        Lowest threshold of the detection curve: peaks are scored down to it (default: the
        threshold itself).
    """
    histogram = check_histogram(histogram)
    if not fwhm_s > 0 or not window_fwhm > 0 or not threshold_sigma >= 0:
        raise ValueError(f"FWHM, window and threshold must be positive, not {fwhm_s!r}, "
                         f"{window_fwhm!r}, {threshold_sigma!r}")
    floor = threshold_sigma if floor_sigma is None else min(floor_sigma, threshold_sigma)
    smoothed = smooth(histogram, sigma_bins)
    level = _background(histogram, smoothed, sigma_bins)
    sigma = noise_sigma(level, sigma_bins)
    chosen = np.asarray(_maxima(smoothed, level + threshold_height(level, sigma_bins, floor),
                                max(1, int(round(min_separation_s / bin_s)))), dtype=np.int64)
    heights = smoothed[chosen] - level
    scores = np.where(heights > 1.0, heights / max(sigma, 1e-300), 0.0)
    positions = (chosen + 0.5) * bin_s
    inside = np.abs(positions - tof_s) <= window_fwhm * fwhm_s
    detected = scores > threshold_sigma
    centres = (np.arange(len(histogram)) + 0.5) * bin_s
    window = np.abs(centres - tof_s) <= window_fwhm * fwhm_s
    target_height = float(smoothed[window].max() - level) if window.any() else 0.0
    other_height = float(smoothed[~window].max() - level) if (~window).any() else 0.0
    hits = np.flatnonzero(detected & inside)
    if len(hits):
        best = _measure(smoothed, int(chosen[hits[0]]), level, sigma_bins, bin_s)
        error = (best.position_s - tof_s) * SPEED_OF_LIGHT / 2
    else:
        error = math.nan
    strongest = np.flatnonzero(detected)
    return Frame(miss=not len(hits), ghost=bool((detected & ~inside).any()),
                 wrong_depth=bool(len(strongest) and not inside[strongest[0]]),
                 depth_error_m=float(error), target_height=target_height,
                 other_height=other_height,
                 target_score=float(scores[inside].max()) if inside.any() else 0.0,
                 other_scores=scores[~inside])


def wilson(successes: int, trials: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a proportion (95 % by default): ``(low, high)``; ``(0, 1)`` for
    no trials."""
    if trials < 0 or not 0 <= successes <= max(trials, 0):
        raise ValueError(f"Need 0 <= successes <= trials, not {successes!r} of {trials!r}")
    if trials == 0:
        return 0.0, 1.0
    p = successes / trials
    z2 = z * z
    centre = (p + z2 / (2 * trials)) / (1 + z2 / trials)
    half = z / (1 + z2 / trials) * math.sqrt(p * (1 - p) / trials + z2 / (4 * trials ** 2))
    return max(0.0, centre - half), min(1.0, centre + half)


def detection_curve(frames, thresholds) -> tuple[np.ndarray, np.ndarray]:
    """P(detect) and false targets per frame at each threshold (noise deviations), from frames
    classified with a ``floor_sigma`` no higher than the lowest threshold.

    A frame detects its target at threshold ``k`` when the target's score exceeds ``k``; its
    false targets are its peaks outside the window scoring above ``k``.
    """
    thresholds = np.asarray(thresholds, dtype=float)
    if not frames:
        raise ValueError("A detection curve needs at least one frame")
    target = np.array([frame.target_score for frame in frames])
    others = np.sort(np.concatenate([frame.other_scores for frame in frames]))
    detect = (target[None, :] > thresholds[:, None]).mean(axis=1)
    false = (len(others) - np.searchsorted(others, thresholds, side="right")) / len(frames)
    return detect, false
