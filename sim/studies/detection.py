"""Target detection judged against a scene's truth: the decision metrics of one frame and of many.

The peaks are :mod:`fliss.analysis.peaks`'s. Per frame (one acquisition), with the true time of
flight known (:func:`classify`):

* **miss**: no detection within ``window_fwhm`` (3) FWHM of the true time of flight;
* **ghost**: a detection anywhere else;
* **wrong depth**: a detection exists and the strongest one is not the true target;
* **depth error**: distance of the strongest detection within the window from the truth.

Over frames: proportions with Wilson score intervals (:func:`wilson`), and the detection curve
(:func:`detection_curve`): P(detect) against false targets per frame as the threshold varies.
"""

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ...analysis.peaks import (check_histogram, local_maxima, measure_peak, noise_sigma, smooth,
                               smoothed_background, threshold_height)
from ...hdl.event import TDC_LSB_S
from ..scene.description import SPEED_OF_LIGHT


__all__ = ["Frame", "classify", "wilson", "proportion", "detection_curve"]


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
        Detection threshold, as :func:`fliss.analysis.peaks.find_peaks` takes it.
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
    level = smoothed_background(histogram, smoothed, sigma_bins)
    sigma = noise_sigma(level, sigma_bins)
    chosen = np.asarray(local_maxima(smoothed, level + threshold_height(level, sigma_bins, floor),
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
        best = measure_peak(smoothed, int(chosen[hits[0]]), level, sigma_bins, bin_s)
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


def proportion(result, name, count, frames):
    """Record ``count`` of ``frames`` in ``result`` as ``name``, ``p_name`` and its Wilson
    interval ``p_name_lo``, ``p_name_hi`` (the columns of a sweep's results)."""
    low, high = wilson(count, frames)
    result[name] = count
    result[f"p_{name}"] = count / frames
    result[f"p_{name}_lo"] = low
    result[f"p_{name}_hi"] = high


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
