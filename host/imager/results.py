"""The imager's data as numpy arrays: per-pixel histograms (:class:`Images`) and depth frames
(:class:`DepthFrames`), from the frames a board sends, and the board calls that acquire them
(:func:`acquire_image`, :func:`acquire_depth`, behind :meth:`fliss.host.board.Board.acquire_image`
and :meth:`~fliss.host.board.Board.acquire_depth`).

Conventions
-----------
* A pixel is named by its sensor address (``pixels``: ``first_pixel …``); arrays are indexed by
  the pixel's place in the frame.
* A depth frame's ``position`` is in bins from the start of bin 0, bin ``b`` covering
  ``[b, b + 1)`` bin widths from the TDC start: the time of flight is ``position * bin_s``
  (:func:`tof_s`) and the depth ``c * tof / 2`` (:func:`depth_m`).
"""

import logging
from dataclasses import dataclass
from typing import Iterable, Optional, Sequence

import numpy as np

from ...hdl.registers import AcquisitionMode
from ..errors import SettingsError
from ..results import FrameCounts
from ..settings import Settings
from ..stream import DepthFrame, HistogramFrame
from .distance import C_M_S, depth_m, tof_s
from .threshold import nothing_detected


__all__ = ["C_M_S", "tof_s", "depth_m", "Images", "DepthFrames", "images_from_frames",
           "depth_from_frames", "acquire_image", "acquire_depth"]

_logger = logging.getLogger(__name__)

@dataclass(frozen=True)
class Images(FrameCounts):
    """Per-pixel histograms from :meth:`fliss.host.board.Board.acquire_image`.

    Attributes
    ----------
    counts : numpy.ndarray
        ``(n, P, N)`` counts: frame, pixel, bin (uint32).
    pixels : numpy.ndarray
        ``(P,)`` the sensor address of each pixel.
    time_s : numpy.ndarray
        ``(N,)`` time of each bin's centre from the TDC start, in seconds.
    frames : numpy.ndarray
        ``(n,)`` the board's frame numbers.
    complete : numpy.ndarray
        ``(n,)`` False for a frame of which part was lost on the link (those bins read 0).
    settings : Settings
        The board's settings during the acquisition.
    """
    counts: np.ndarray
    pixels: np.ndarray
    time_s: np.ndarray
    frames: np.ndarray
    complete: np.ndarray
    settings: Settings

    @property
    def intensity(self) -> np.ndarray:
        """Counts of each pixel in each frame, ``(n, P)``."""
        return self.counts.sum(axis=2, dtype=np.uint64)


@dataclass(frozen=True)
class DepthFrames:
    """Depth frames from :meth:`fliss.host.board.Board.acquire_depth`.

    Attributes
    ----------
    depth_m : numpy.ndarray
        ``(n, P)`` distance of each pixel's strongest peak in metres; NaN where not detected.
    height, background : numpy.ndarray
        ``(n, P)`` the peak's height and the background level, in counts.
    detected : numpy.ndarray
        ``(n, P)`` True where the peak cleared the threshold.
    position : numpy.ndarray
        ``(n, P)`` the peak's position in bins (fractional), as the board sent it.
    pixels : numpy.ndarray
        ``(P,)`` the sensor address of each pixel.
    frames : numpy.ndarray
        ``(n,)`` the board's frame numbers.
    settings : Settings
        The board's settings during the acquisition.
    """
    depth_m: np.ndarray
    height: np.ndarray
    background: np.ndarray
    detected: np.ndarray
    position: np.ndarray
    pixels: np.ndarray
    frames: np.ndarray
    settings: Settings

    @property
    def tof_s(self) -> np.ndarray:
        """``(n, P)`` time of flight in seconds (NaN where not detected)."""
        return self.depth_m * 2 / C_M_S

    @property
    def detection_rate(self) -> np.ndarray:
        """``(P,)`` fraction of frames in which each pixel detected a peak."""
        return self.detected.mean(axis=0) if len(self.detected) else np.zeros(len(self.pixels))


def images_from_frames(frames: Sequence[HistogramFrame], settings: Settings) -> Images:
    """:class:`Images` from :class:`~fliss.host.stream.HistogramFrame` items of one split.

    Raises :exc:`ValueError` if the frames differ in split (pixels, first pixel or bin shift).
    """
    if not frames:
        raise ValueError("no frames")
    first = frames[0]
    for frame in frames:
        if (frame.pixel_bits, frame.first_pixel, frame.shift) != \
                (first.pixel_bits, first.first_pixel, first.shift):
            raise ValueError(f"frame {frame.frame} has another pixel split than frame "
                             f"{first.frame}")
    bins = len(first.image[0])
    bin_s = settings.code_s * (1 << first.shift)
    return Images(counts=np.stack([frame.image for frame in frames]),
                  pixels=first.first_pixel + np.arange(1 << first.pixel_bits),
                  time_s=(np.arange(bins) + 0.5) * bin_s,
                  frames=np.array([frame.frame for frame in frames], dtype=np.uint32),
                  complete=np.array([frame.complete for frame in frames], dtype=bool),
                  settings=settings)


def depth_from_frames(frames: Sequence[DepthFrame], settings: Settings) -> DepthFrames:
    """:class:`DepthFrames` from :class:`~fliss.host.stream.DepthFrame` items of one split.

    Raises :exc:`ValueError` if the frames differ in pixels or bin shift.
    """
    if not frames:
        raise ValueError("no frames")
    first = frames[0]
    for frame in frames:
        if (len(frame.position), frame.first_pixel, frame.shift) != \
                (len(first.position), first.first_pixel, first.shift):
            raise ValueError(f"frame {frame.frame} has another pixel split than frame "
                             f"{first.frame}")
    detected = np.stack([np.asarray(frame.detected, dtype=bool) for frame in frames])
    position = np.stack([np.asarray(frame.position, dtype=float) for frame in frames])
    position = np.where(detected, position, np.nan)
    bin_s = settings.code_s * (1 << first.shift)
    return DepthFrames(depth_m=depth_m(tof_s(position, bin_s)),
                       height=np.stack([np.asarray(frame.height, dtype=float)
                                        for frame in frames]),
                       background=np.stack([np.asarray(frame.background, dtype=float)
                                            for frame in frames]),
                       detected=detected, position=position,
                       pixels=first.first_pixel + np.arange(len(first.position)),
                       frames=np.array([frame.frame for frame in frames], dtype=np.uint32),
                       settings=settings)


def _split_of(item):
    # (pixels, first pixel, bin shift) of a frame
    if isinstance(item, HistogramFrame):
        return 1 << item.pixel_bits, item.first_pixel, item.shift
    return len(item.position), item.first_pixel, item.shift


def _collect(board, n, kind, mode, timeout_s):
    # ``n`` items of type ``kind`` from the board in readout ``mode``, of the split set when
    # it started (others, sent before the start, are left out and logged); stops the board.
    if n < 1:
        raise SettingsError(f"n must be at least 1, not {n!r}")
    settings = board._start(mode)
    split = (settings.pixels, settings.registers["first_pixel"], settings.registers["bin_shift"])
    wait = board.wait_s(settings) if timeout_s is None else float(timeout_s)
    items, other = [], 0
    with board._stopping():
        for item in board.client.stream(idle_timeout_s=wait, data_timeout_s=wait):
            if not isinstance(item, kind):
                continue
            if _split_of(item) != split:
                other += 1
                continue
            items.append(item)
            if len(items) >= n:
                break
    if other:
        _logger.warning("%d frames of another pixel split than the settings' were left out",
                        other)
    return items, settings


def acquire_image(board, n: int = 1, *, timeout_s: Optional[float] = None) -> Images:
    """``n`` frames of per-pixel histograms from ``board`` (a :class:`~fliss.host.board.Board`)
    at its settings, in histogram readout; see :meth:`fliss.host.board.Board.acquire_image`."""
    frames, settings = _collect(board, n, HistogramFrame, AcquisitionMode.HISTOGRAM, timeout_s)
    result = images_from_frames(frames, settings)
    if not result.complete.all():
        _logger.warning("%d of %d frames arrived incomplete (bins lost on the link)",
                        int((~result.complete).sum()), n)
    _warn_gaps(result.frames, n)
    return result


def acquire_depth(board, n: int = 1, *, timeout_s: Optional[float] = None) -> DepthFrames:
    """``n`` depth frames from ``board`` at its settings, in depth readout; see
    :meth:`fliss.host.board.Board.acquire_depth`."""
    frames, settings = _collect(board, n, DepthFrame, AcquisitionMode.DEPTH, timeout_s)
    result = depth_from_frames(frames, settings)
    _warn_gaps(result.frames, n)
    if not result.detected.any():
        _logger.warning("%s", nothing_detected(len(frames), int(result.height.max()),
                                                frames[0].threshold, style="keyword"))
    return result


def _warn_gaps(frames: Iterable[int], n: int) -> None:
    frames = np.asarray(frames, dtype=np.int64)
    lost = int((np.diff(frames) % (1 << 32) - 1).sum()) if len(frames) > 1 else 0
    if lost:
        _logger.warning("%d frames were lost on the link between the first and the last of %d",
                        lost, n)
