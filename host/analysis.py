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
* A peak is significant when background alone makes one like it in a histogram with a
  probability of at most :data:`~fliss.analysis.peaks.FALSE_ALARM` (exact Poisson tails, see
  :mod:`fliss.analysis.peaks`).
* Which peak is whose: :mod:`fliss.host.roles`. A suppression ratio is worked out only when the
  victim's peak is known.
* At high flux a single-hit TDC piles up (it keeps one photon a laser cycle): :func:`analyze`
  with ``pileup="first"`` or ``"last"`` and the histogram's number of laser cycles measures
  the peaks on the corrected histogram (:mod:`fliss.analysis.pileup`: Coates' correction, or
  its counterpart for a TDC that keeps the last photon), ``cycles × λ_i``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple, Optional

import numpy as np
from numpy.typing import ArrayLike

from ..hdl.event import TDC_LSB_S
from ..analysis.peaks import (FALSE_ALARM, FWHM_PER_SIGMA, Peak, background, detection_height,
                              find_peaks, noise_sigma, smooth)
from ..analysis.peaks import check_histogram as _check_histogram
from ..analysis.pileup import KEEPS, PileupError, coates, corrected_peaks
from .roles import AGGRESSOR_ROLE, UNKNOWN_ROLE, Roles, assign, relation


__all__ = ["analyze", "Analysis", "FWHM_PER_SIGMA", "Peak", "Suppression", "background", "smooth",
           "noise_sigma", "find_peaks", "identify", "suppression_db", "suppression",
           "relative_deviation", "mean_std", "KEEPS", "PileupError", "coates"]


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

    @property
    def bound(self) -> str:
        """``"lower"`` when ``s_db`` is a lower bound (``limited``), else ``"equal"``."""
        return "lower" if self.limited else "equal"

    @property
    def relation(self) -> str:
        """``">="`` or ``"="``, as the text gives S."""
        return ">=" if self.limited else "="


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
                bin_s: float = TDC_LSB_S, sigma_bins: float = 5.0,
                false_alarm: float = FALSE_ALARM, tolerance_s: float = 1.5e-9) -> Suppression:
    """Suppression ratio of one histogram, Pa being the highest aggressor peak.

    The victim's and the aggressors' peaks are told apart by reference positions (see
    :func:`identify`). When no aggressor peak passes the significance test, Pa is the height of
    the least peak that would (:func:`~fliss.analysis.peaks.detection_height`) and the result
    is marked ``limited`` (a lower bound of S). Raises
    :exc:`ValueError` when the victim's peak is not found.
    """
    histogram = _check_histogram(histogram)
    level = background(histogram, sigma_bins=sigma_bins)
    peaks = find_peaks(histogram, bin_s=bin_s, sigma_bins=sigma_bins, false_alarm=false_alarm,
                       level=level)
    victim, aggressors, _ = identify(peaks, victim_s, aggressors_s, tolerance_s=tolerance_s)
    if victim is None:
        raise ValueError(f"No victim peak within {tolerance_s * 1e9:g} ns of "
                         f"{victim_s * 1e9:g} ns")
    return _ratio(victim, aggressors, level, sigma_bins, len(histogram), false_alarm)


def _ratio(victim, aggressors, level, sigma_bins, bins, false_alarm):
    if aggressors:
        pa, limited = max(peak.height for peak in aggressors), False
    else:
        pa, limited = detection_height(level, sigma_bins, bins, false_alarm), True
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


class Analysis(NamedTuple):
    """What :func:`analyze` found in one histogram: the background (counts per bin), the
    peaks (highest first), their roles (:mod:`fliss.host.roles`), the suppression (None when
    it cannot be told) and a note on the roles or on why there is no suppression."""
    level: float
    peaks: list
    suppression: Optional[Suppression]
    note: str
    roles: Roles


def analyze(histogram, bin_s, *, configuration=None, victim_s=None, aggressors_s=(),
            tolerance_s=1.5e-9, shift=0, false_alarm=FALSE_ALARM, pileup=None,
            cycles=None, dead_time_s=0.0) -> Analysis:
    """Background, peaks, their roles and (when the victim's peak is known) the suppression of
    one histogram of a capture taken with the registers ``configuration``; with ``pileup``
    (``"first"`` or ``"last"``, the photon the TDC keeps), the peaks found on the histogram as
    recorded and measured on the histogram corrected for pile-up over its ``cycles`` laser
    cycles, the background too (:func:`~fliss.analysis.pileup.corrected_peaks`); keeping the
    last photon, with the SPAD's non-paralysable ``dead_time_s`` (in whole bins).

    S is against the highest aggressor peak; a lower bound (against the least significant
    peak) when the aggressor was on (or ``aggressors_s`` given) and no aggressor peak stands;
    not worked out when the victim's peak is unknown, when a peak is left whose role is
    unknown (it might be the aggressor's), or with the aggressor off."""
    sigma_bins = max(5.0 / (1 << shift), 1.0)
    if pileup is not None:
        level, peaks = corrected_peaks(histogram, cycles, pileup, bin_s=bin_s,
                                       sigma_bins=sigma_bins, false_alarm=false_alarm,
                                       dead_bins=int(round(dead_time_s / bin_s)))
    else:
        level = background(histogram, sigma_bins=sigma_bins)
        peaks = find_peaks(histogram, bin_s=bin_s, sigma_bins=sigma_bins, level=level,
                           false_alarm=false_alarm)
    roles = assign(peaks, configuration or {}, victim_s=victim_s, aggressors_s=aggressors_s,
                   tolerance_s=tolerance_s)
    result, note = None, roles.reason
    unknown = [peak for peak, role in zip(peaks, roles.roles) if role == UNKNOWN_ROLE]
    if roles.victim is None:
        pass
    elif AGGRESSOR_ROLE in roles.roles or not unknown and (
            aggressors_s or relation(configuration or {})[0] in ("coherent", "spread")):
        result = _ratio(roles.victim, roles.aggressors, level, sigma_bins, len(histogram),
                        false_alarm)
        if result.limited:
            note += "; no aggressor peak above the detection threshold"
        if unknown:
            note += f"; left out of S: {_ns(unknown)} (at neither position given)"
    elif unknown:
        note += (f"; S unknown: the peak{'s' * (len(unknown) > 1)} at {_ns(unknown)} "
                 f"{'are' if len(unknown) > 1 else 'is'} neither the victim's nor at "
                 f"--aggressor-tof" if aggressors_s else
                 f"; S unknown: the role of the peak{'s' * (len(unknown) > 1)} at "
                 f"{_ns(unknown)} is unknown (give --aggressor-tof)")
    else:
        note += "; no aggressor: no suppression to measure"
    return Analysis(level, peaks, result, note, roles)


def _ns(peaks):
    return ", ".join(f"{peak.position_s * 1e9:.1f}" for peak in peaks) + " ns"
