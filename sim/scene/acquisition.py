"""Acquisitions of the scene simulator: one continuous run cut into integration times.

:func:`acquire` returns the histograms (``TDC_CODES`` bins, as the histogram engine delivers
them) and photon counters of consecutive acquisitions.
"""

from dataclasses import dataclass, field

import numpy as np

from ...protocol.events import EVENT_DTYPE
from .checks import check_number
from .description import COUNTERS, TDC_CODES
from .array import simulation_for


__all__ = ["Acquisitions", "acquire", "histogram"]


def histogram(events):
    """Histogram of the timestamps of ``events``: ``TDC_CODES`` bins, ``numpy.int64``."""
    return np.bincount(np.asarray(events["timestamp"], dtype=np.int64), minlength=TDC_CODES)


@dataclass
class Acquisitions:
    """Consecutive acquisitions of one continuous run.

    Attributes
    ----------
    histograms : numpy.ndarray
        ``(acquisitions, TDC_CODES)`` counts per TDC code.
    counts : numpy.ndarray
        ``(acquisitions, sources, len(COUNTERS))`` photon counters.
    cycles : numpy.ndarray
        Laser cycles in each acquisition.
    sources : tuple of str
    t_int_cycles : int
        Integration time in clock cycles.
    """

    histograms: np.ndarray
    counts: np.ndarray
    cycles: np.ndarray
    sources: tuple
    t_int_cycles: int
    events: list = field(default_factory=list)


def acquire(scene, t_int_s, acquisitions, *, seed=None, chunk_cycles=1 << 16, keep_events=False,
            progress=None, aggressor_edges=None):
    """Run the scene for ``acquisitions`` consecutive integration times of ``t_int_s`` each.

    Acquisition ``a`` holds the laser cycles whose TDC start falls in clock cycles
    ``[a * T, (a + 1) * T)``, ``T = round(t_int_s * clock_hz)``, as the histogram engine
    integrates over a time set in clock cycles; the delay sequences run on across acquisitions.
    ``progress``, if given, is called with the number of laser cycles after each chunk.
    ``aggressor_edges``, if given, holds the laser triggers of each aggressor in the victim's
    clock cycles (:meth:`~.photons.Simulation.feed_aggressor`), instead of their own schedules.
    With a pixel array (``scene.pixels``) the histograms hold the events of every pixel
    together; ``keep_events`` keeps each event's pixel address and collision flag.
    """
    check_number(t_int_s, "Integration time (s)", positive=True)
    if isinstance(acquisitions, bool) or not isinstance(acquisitions, (int, np.integer)) \
            or acquisitions < 1:
        raise ValueError(f"Number of acquisitions must be a positive integer, "
                         f"not {acquisitions!r}")
    t_int_cycles = int(round(t_int_s * scene.clock_hz))
    if t_int_cycles < 1:
        raise ValueError(f"Integration time {t_int_s!r} s is shorter than one clock cycle")
    simulation = simulation_for(scene, seed=seed, chunk_cycles=chunk_cycles,
                            external_aggressors=aggressor_edges is not None)
    if aggressor_edges is not None:
        if len(aggressor_edges) != len(scene.aggressors):
            raise ValueError(f"Give the triggers of each of the {len(scene.aggressors)} "
                             f"aggressors, not of {len(aggressor_edges)}")
        for index, edges in enumerate(aggressor_edges):
            simulation.feed_aggressor(index, edges)
    histograms = np.zeros((acquisitions, TDC_CODES), dtype=np.int64)
    counts = np.zeros((acquisitions, len(scene.sources), len(COUNTERS)), dtype=np.int64)
    cycles = np.zeros(acquisitions, dtype=np.int64)
    kept = []
    for index in range(acquisitions):
        end = (index + 1) * t_int_cycles
        pieces = []
        while simulation.next_start_cycle < end:
            chunk = simulation.step(until_cycle=end)
            histograms[index] += histogram(chunk.events)
            counts[index] += chunk.counts
            cycles[index] += chunk.cycles
            if keep_events:
                pieces.append(chunk.events)
            if progress is not None:
                progress(chunk.cycles)
        if keep_events:
            kept.append(np.concatenate(pieces) if pieces else np.zeros(0, dtype=EVENT_DTYPE))
    return Acquisitions(histograms, counts, cycles, scene.sources, t_int_cycles, kept)
