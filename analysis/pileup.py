"""Pile-up correction of a single-hit TCSPC histogram: Coates' for a TDC that keeps the first
photon of a laser cycle, and its counterpart for one that keeps the last.

A single-hit TDC records at most one photon per laser cycle. With ``λ_i`` the mean number of
photons (Poisson) that would be detected in bin ``i`` of a cycle, the first photon falls in bin
``i`` when none fell in the bins before and at least one in bin ``i``. Of ``N`` cycles, the
``M_i = N − Σ_{j<i} n_j`` cycles with no count before bin ``i`` are the ones "at risk" there,
and ``n_i`` of them record bin ``i``: ``n_i / M_i`` estimates ``1 − exp(−λ_i)``, so

    λ_i = −ln(1 − n_i / M_i)                     (Coates 1968, first photon)

whatever the rates of the other bins. Keeping the last photon, the bins after play that part:
``M_i = N − Σ_{j>i} n_j``. At low flux ``λ_i ≈ n_i / N``; at high flux the raw histogram piles
up towards the kept end (first photon: its early bins; last: its late ones) and a peak's
position moves with it; the corrected ``N λ_i`` does not.

The estimate's standard error, from the binomial ``n_i`` of ``M_i``: ``σ_i = sqrt(p_i / ((1 −
p_i) M_i))`` with ``p_i = n_i / M_i``.

A TDC that keeps the last photon behind a non-paralysable SPAD dead time of ``D`` bins
(``dead_bins``): bin ``i`` is recorded when an avalanche falls there and no photon comes after
its dead time, ``n_i = N a_i S_i`` with ``S_i = exp(−Σ_{k ≥ i+D} λ_k)`` and ``a_i = (1 −
e^{−λ_i}) R_i``, ``R_i = 1 − Σ_{i−D<j<i} a_j`` (:func:`_last_with_dead_time`). A SPAD whose
dead time outlasts the echo pulse detects only its first photon, whichever photon the TDC
keeps: the counterpart without the dead time is then wrong (it doubles the bias).

What it assumes: Poisson arrivals independent from bin to bin, a SPAD ready at the start of
the window, and ``N`` the number of laser cycles (TDC windows) the histogram holds, each
recorded at most once. A bin where every cycle at risk recorded a count has no finite
estimate, nor have the bins no cycle reaches after it: :exc:`PileupError`.

:func:`corrected_peaks` finds the peaks of the corrected histogram, tested against its own
noise.
"""

import math
from statistics import NormalDist
from typing import NamedTuple

import numpy as np

from .peaks import (FALSE_ALARM, local_maxima, measure_peak, smooth, smoothed_background,
                    window_bins)


__all__ = ["KEEPS", "PileupError", "Correction", "coates", "corrected_peaks"]

#: Which photon of a cycle the TDC keeps.
KEEPS = ("first", "last")


class PileupError(ValueError):
    """A histogram the pile-up correction cannot take; the message says why."""


class Correction(NamedTuple):
    """Coates' estimate of a histogram: ``rate`` (mean detections per cycle in each bin,
    ``λ_i``), its standard error ``sigma``, and ``at_risk`` (the cycles ``M_i`` with no
    count kept before bin ``i``, ``first``, or after it, ``last``)."""
    rate: np.ndarray
    sigma: np.ndarray
    at_risk: np.ndarray

    def counts(self, cycles):
        """The corrected histogram in counts: ``cycles × rate``."""
        return cycles * self.rate


def coates(histogram, cycles, keep="first", dead_bins=0):
    """Coates' correction (``keep="first"``) or its counterpart for a TDC that keeps the last
    photon (``keep="last"``) of ``histogram`` (counts per bin) over ``cycles`` laser cycles;
    with ``keep="last"`` and ``dead_bins`` above 1, for a non-paralysable SPAD blind for that
    many bins after each avalanche (:func:`_last_with_dead_time`). Returns a
    :class:`Correction`. Raises :exc:`PileupError`."""
    if keep not in KEEPS:
        raise PileupError(f"the TDC keeps the 'first' or the 'last' photon, not {keep!r}")
    if isinstance(dead_bins, bool) or not isinstance(dead_bins, (int, np.integer)) \
            or dead_bins < 0:
        raise PileupError(f"the dead time in bins must be a whole number, not negative, not "
                          f"{dead_bins!r}")
    counts = np.asarray(histogram)
    if counts.ndim != 1 or not len(counts) or not np.issubdtype(counts.dtype, np.number) \
            or not np.all(np.isfinite(counts)) or np.any(counts < 0) \
            or np.any(counts != np.round(counts)):
        raise PileupError("a histogram is a list of counts: whole numbers, not negative")
    if isinstance(cycles, bool) or not isinstance(cycles, (int, np.integer)) or cycles < 1:
        raise PileupError(f"the number of laser cycles must be a whole number of at least 1, "
                          f"not {cycles!r}")
    counts = counts.astype(np.float64)
    total = counts.sum()
    if total > cycles:
        raise PileupError(f"the histogram holds {int(total)} counts, more than its {cycles} "
                          f"laser cycles: a single-hit TDC records one photon a cycle at most "
                          f"(the cycle count is not this histogram's)")
    if keep == "last" and dead_bins > 1:
        return _last_with_dead_time(counts, cycles, int(dead_bins))
    ordered = counts if keep == "first" else counts[::-1]
    before = np.concatenate(([0.0], np.cumsum(ordered)[:-1]))
    at_risk = cycles - before
    full = np.flatnonzero((ordered >= at_risk) & (ordered > 0))
    if len(full):
        index = int(full[0]) if keep == "first" else len(counts) - 1 - int(full[0])
        raise PileupError(f"bin {index}: every laser cycle left there ({int(at_risk[full[0]])}) "
                          f"recorded it: its rate is beyond what {cycles} cycles measure")
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(at_risk > 0, ordered / np.maximum(at_risk, 1.0), np.nan)
        rate = -np.log1p(-p)
        sigma = np.sqrt(p / ((1.0 - p) * at_risk))
    if keep == "last":
        rate, sigma, at_risk = rate[::-1], sigma[::-1], at_risk[::-1]
    return Correction(rate, sigma, at_risk)


def _last_with_dead_time(counts, cycles, dead):
    """The last photon's counterpart for a non-paralysable SPAD blind ``dead`` bins after an
    avalanche (see the module): bin ``i`` is recorded when an avalanche falls there (a photon,
    the SPAD ready: ``a_i = p_i R_i``, ``R_i = 1 − Σ_{i−dead<j<i} a_j``, at most one avalanche
    in a dead time) and no photon comes from its dead time's end on (``S_i = exp(−Σ_{k ≥
    i+dead} λ_k)``): ``n_i = N a_i S_i``. Backwards from the last bin every ``S_j`` a step
    needs is known (``j + dead`` > ``i``), so ``λ_i = −ln(1 − a_i / R_i)`` in one pass."""
    bins = len(counts)
    rate = np.zeros(bins)
    at_risk = np.zeros(bins)
    tail = np.zeros(bins + 1)               # tail[k]: Σ of the rates from bin k on
    avalanche = np.zeros(bins)              # a_j: known once the rates from j + dead on are
    for j in range(max(bins - dead, 0), bins):
        avalanche[j] = counts[j] / cycles
    window = float(avalanche[max(bins - dead, 0):bins - 1].sum())    # a_j, i - dead < j < i
    for i in range(bins - 1, -1, -1):
        at_risk[i] = cycles * math.exp(-tail[min(i + dead, bins)]) * (1.0 - window)
        if counts[i] > 0 and counts[i] >= at_risk[i]:
            raise PileupError(f"bin {i}: the laser cycles left there with a ready SPAD "
                              f"({at_risk[i]:.4g}) all recorded it: its rate is beyond what "
                              f"{cycles} cycles measure")
        rate[i] = -math.log1p(-counts[i] / at_risk[i]) if counts[i] > 0 else 0.0
        tail[i] = tail[i + 1] + rate[i]
        # The window moves one bin earlier: a_{i-dead} comes in (its S needs tail[i]),
        # a_{i-1} goes out
        if i - dead >= 0:
            avalanche[i - dead] = counts[i - dead] / (cycles * math.exp(-tail[i]))
            window += avalanche[i - dead]
        if i >= 1:
            window -= avalanche[i - 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        p = -np.expm1(-rate)
        sigma = np.sqrt(p / ((1.0 - p) * at_risk))
    return Correction(rate, sigma, at_risk)


def corrected_peaks(histogram, cycles, keep, *, bin_s, sigma_bins=5.0, false_alarm=FALSE_ALARM,
                    dead_bins=0):
    """``(level, peaks)`` of a histogram corrected for pile-up (``cycles × λ``), as
    :func:`~fliss.analysis.peaks.find_peaks` finds them but with the corrected counts' own
    noise: a maximum of the smoothed corrected histogram is a peak when its test window
    (:func:`~fliss.analysis.peaks.window_bins`) rises above the background ``level`` by
    ``z`` standard deviations of the window's sum, the variance of each bin being the
    estimate's binomial one (:class:`Correction`: ``sigma``; at least that of the
    background's rate, so that an empty bin is not taken as exact), and ``z`` the Gaussian
    quantile that background alone passes in ``false_alarm`` of histograms. (The Poisson test
    of the recorded counts does not hold there: pile-up tilts their background, and the
    corrected counts' noise grows where few cycles are left at risk.) Highest first."""
    result = coates(histogram, cycles, keep, dead_bins)
    counts = result.counts(cycles)
    smoothed = smooth(counts, sigma_bins)
    level = smoothed_background(counts, smoothed, sigma_bins)
    p = np.maximum(-np.expm1(-result.rate), -math.expm1(-level / cycles))
    variance = cycles ** 2 * p / ((1.0 - p) * np.maximum(result.at_risk, 1))
    width = window_bins(sigma_bins, len(counts))
    inner = smoothed[1:-1]
    maxima = np.flatnonzero((inner >= smoothed[:-2]) & (inner > smoothed[2:])) + 1
    first = np.clip(maxima - width // 2, 0, len(counts) - width)
    sums = np.concatenate(([0.0], np.cumsum(counts)))
    spread = np.concatenate(([0.0], np.cumsum(variance)))
    above = sums[first + width] - sums[first] - level * width
    noise = np.sqrt(spread[first + width] - spread[first])
    windows = max(len(counts) / width, 1.0)
    z = NormalDist().inv_cdf(1.0 - false_alarm / windows)
    significant = maxima[above >= z * noise]
    separation = max(1, int(round(5e-9 / bin_s)))
    chosen = local_maxima(smoothed, level, separation, among=significant)
    return level, [measure_peak(smoothed, index, level, sigma_bins, bin_s) for index in chosen]
