"""What the Python API's histogram and raw acquisitions return (:class:`Histograms`,
:class:`Events`), as numpy arrays; the imager's are in :mod:`fliss.host.imager.results`."""

from dataclasses import dataclass

import numpy as np

from .settings import Settings


__all__ = ["Histogram", "FrameCounts", "Histograms", "Events"]


@dataclass(frozen=True)
class Histogram:
    """One histogram.

    Attributes
    ----------
    counts : numpy.ndarray
        Counts per bin (uint32).
    time_s : numpy.ndarray
        Time of each bin's centre from the TDC start, in seconds.
    frame : int
        The board's histogram number.
    complete : bool
        False if part of it was lost on the link (those bins read 0).
    """
    counts: np.ndarray
    time_s: np.ndarray
    frame: int
    complete: bool


class FrameCounts:
    """What :class:`Histograms` and :class:`~fliss.host.imager.results.Images` share: ``counts``, one
    frame per row of its first axis, and the board's ``settings``."""

    @property
    def bin_s(self) -> float:
        """Width of a bin, in seconds."""
        return self.settings.bin_s

    @property
    def total(self) -> np.ndarray:
        """The frames' counts summed (over ``counts``' first axis): ``(bins,)`` of
        :class:`Histograms`, each pixel's ``(P, N)`` of :class:`~fliss.host.imager.results.Images`."""
        return self.counts.sum(axis=0, dtype=np.uint64)


@dataclass(frozen=True)
class Histograms(FrameCounts):
    """Histograms from :meth:`~fliss.host.board.Board.acquire`.

    Attributes
    ----------
    counts : numpy.ndarray
        ``(n, bins)`` counts, one row per histogram (uint32).
    time_s : numpy.ndarray
        ``(bins,)`` time of each bin's centre from the TDC start, in seconds.
    frames : numpy.ndarray
        ``(n,)`` the board's histogram numbers (consecutive unless some were lost).
    complete : numpy.ndarray
        ``(n,)`` False for a histogram of which part was lost on the link.
    settings : Settings
        The board's settings during the acquisition.
    """
    counts: np.ndarray
    time_s: np.ndarray
    frames: np.ndarray
    complete: np.ndarray
    settings: Settings

    @property
    def lost(self) -> int:
        """Histograms that never arrived between the first and the last (gaps in ``frames``)."""
        if len(self.frames) < 2:
            return 0
        gaps = np.diff(self.frames.astype(np.int64)) % (1 << 32) - 1
        return int(gaps.sum())


@dataclass(frozen=True)
class Events:
    """Raw events from :meth:`~fliss.host.board.Board.acquire_raw`.

    Attributes
    ----------
    events : numpy.ndarray
        A structured array (:data:`fliss.protocol.events.EVENT_DTYPE`): ``timestamp`` (TDC codes),
        ``address`` (pixel), ``collision``, ``pulse`` (laser cycle index).
    duration_s : float
        The board's time the acquisition spans, in seconds: the pulses it fired times their
        mean interval (the period, plus the mean delay in interval mode). On the model board
        and a real board about the ``duration`` asked for; a simulated board, slower than real
        time, acquires for less.
    dropped : int
        Events the board dropped (its raw FIFO full: the link was too slow).
    settings : Settings
        The board's settings during the acquisition.
    pulses : int
        Laser pulses the board fired during the acquisition (its STATUS ``pulses``).
    """
    events: np.ndarray
    duration_s: float
    dropped: int
    settings: Settings
    pulses: int = 0

    @property
    def time_s(self) -> np.ndarray:
        """Each event's timestamp in seconds from the TDC start."""
        return self.events["timestamp"] * self.settings.code_s

    def __len__(self):
        return len(self.events)
