"""Per-pixel analysis of the imager's captures: one :class:`PixelResult` per pixel, from the
per-pixel histograms of an image capture (the peak finder of :mod:`fliss.analysis.peaks` on
each pixel's histogram) or from the depth frames of a depth capture (their median).

Conventions as in :mod:`fliss.host.analysis`: a peak's time of flight is its position from the
TDC start, at bin centres; depth is ``c * tof / 2``.
"""

import math
from dataclasses import asdict, dataclass
from typing import List, Optional

import numpy as np

from ...analysis.peaks import FALSE_ALARM, background, find_peaks
from ..kinds import names, of_capture
from .results import C_M_S


__all__ = ["PixelResult", "sigma_bins", "pixel_peak", "image_table", "frame_depths",
           "depth_table", "capture_table", "as_records"]


@dataclass(frozen=True)
class PixelResult:
    """What one pixel saw.

    Attributes
    ----------
    address : int
        The pixel's sensor address.
    detected : bool
        A peak passed the significance test (image: :func:`~fliss.analysis.peaks.find_peaks`),
        or the board's depth threshold in at least half the frames (depth).
    depth_m, tof_s : float
        Distance and time of flight of its strongest peak (NaN when not detected).
    height : float
        The peak's height above the background, in counts per bin (image: of the summed
        histogram; depth: the median over the frames that detected it).
    background : float
        Background level in counts per bin (depth: the median over the frames).
    detection_rate : float or None
        Fraction of frames that detected a peak (depth captures only).
    frames : int
        Frames used.
    """
    address: int
    detected: bool
    depth_m: float
    tof_s: float
    height: float
    background: float
    detection_rate: Optional[float]
    frames: int


def sigma_bins(shift: int) -> float:
    """Smoothing of the peak finder, in bins: 5 codes (250 ps), at least one bin."""
    return max(5.0 / (1 << shift), 1.0)


def pixel_peak(histogram, bin_s: float, shift: int, *, false_alarm: float = FALSE_ALARM):
    """``(tof_s, height, background)`` of the tallest peak of one pixel's histogram; tof_s and
    height are NaN when no peak passes the significance test of
    :func:`~fliss.analysis.peaks.find_peaks` (``false_alarm``: the chance that background
    alone makes a peak in the histogram)."""
    histogram = np.asarray(histogram, dtype=np.int64)
    sigma = sigma_bins(shift)
    level = background(histogram, sigma_bins=sigma)
    peaks = find_peaks(histogram, bin_s=bin_s, sigma_bins=sigma, level=level,
                       false_alarm=false_alarm)
    if not peaks:
        return math.nan, math.nan, level
    return peaks[0].position_s, peaks[0].height, level


def image_table(counts, pixels, bin_s: float, shift: int, *, frames: int = 1,
                false_alarm: float = FALSE_ALARM) -> List[PixelResult]:
    """One :class:`PixelResult` per pixel of ``counts`` ``(P, N)`` (histograms summed over
    ``frames`` frames), ``pixels`` their addresses."""
    counts = np.asarray(counts)
    if counts.ndim != 2 or len(counts) != len(pixels):
        raise ValueError(f"expected counts of shape (pixels, bins) for {len(pixels)} pixels, "
                         f"not {counts.shape}")
    rows = []
    for address, histogram in zip(pixels, counts):
        tof, height, level = pixel_peak(histogram, bin_s, shift,
                                        false_alarm=false_alarm)
        rows.append(PixelResult(int(address), bool(np.isfinite(tof)), tof * C_M_S / 2, tof,
                                height, level, None, int(frames)))
    return rows


def frame_depths(counts, bin_s: float, shift: int, *, false_alarm: float = FALSE_ALARM
                 ) -> np.ndarray:
    """Depth in metres of each pixel in each frame of ``counts`` ``(n, P, N)``: ``(n, P)``,
    NaN where no peak is found."""
    counts = np.asarray(counts)
    depths = np.full(counts.shape[:2], np.nan)
    for index in np.ndindex(*counts.shape[:2]):
        tof = pixel_peak(counts[index], bin_s, shift, false_alarm=false_alarm)[0]
        depths[index] = tof * C_M_S / 2
    return depths


def depth_table(depth: dict, pixels, complete=None) -> List[PixelResult]:
    """One :class:`PixelResult` per pixel from depth frames: ``depth`` holds ``depth_m``,
    ``height``, ``background``, ``detected`` ``(n, P)`` arrays; ``complete`` ``(n,)`` says
    which frames arrived (the others are left out)."""
    detected = np.asarray(depth["detected"], dtype=bool)
    keep = np.ones(len(detected), dtype=bool) if complete is None else \
        np.asarray(complete, dtype=bool)
    detected = detected[keep]
    frames = len(detected)
    rows = []
    for place, address in enumerate(pixels):
        hits = detected[:, place]
        rate = float(hits.mean()) if frames else 0.0
        found = np.asarray(depth["depth_m"])[keep][hits, place]
        metres = float(np.median(found)) if len(found) else math.nan
        heights = np.asarray(depth["height"])[keep][hits, place]
        levels = np.asarray(depth["background"])[keep][:, place]
        rows.append(PixelResult(
            int(address), bool(frames and rate >= 0.5), metres, metres * 2 / C_M_S,
            float(np.median(heights)) if len(heights) else math.nan,
            float(np.nanmedian(levels)) if np.isfinite(levels).any() else math.nan,
            rate, frames))
    return rows


def capture_table(capture, *, false_alarm: float = FALSE_ALARM) -> List[PixelResult]:
    """The per-pixel table of an image or depth :class:`~fliss.host.fileformat.Capture`
    (complete frames only). Raises :exc:`ValueError` for another mode."""
    if not of_capture(capture).imager:
        raise ValueError(f"{capture.path}: a {capture.mode} capture has no pixels; "
                         f"per-pixel tables need --readout {names(lambda kind: kind.imager, 'or')}")
    if capture.depth is not None:
        return depth_table(capture.depth, capture.pixels, capture.complete)
    rows = capture.histograms[capture.complete]
    total = rows.sum(axis=0, dtype=np.int64) if len(rows) else \
        np.zeros(capture.histograms.shape[1:], dtype=np.int64)
    return image_table(total, capture.pixels, capture.bin_s, capture.shift, frames=len(rows),
                       false_alarm=false_alarm)


def as_records(rows: List[PixelResult]) -> List[dict]:
    """The rows as dicts for JSON (NaN as None)."""
    def plain(value):
        return None if isinstance(value, float) and not math.isfinite(value) else value
    return [{key: plain(value) for key, value in asdict(row).items()} for row in rows]
