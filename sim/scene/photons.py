"""Photon generation and detection of the scene simulator, laser cycle after laser cycle.

:class:`Simulation` streams the :class:`~fliss.sim.scene.description.Scene` a chunk of laser
cycles at a time; each :class:`Chunk` holds the events the sensor delivers and the photon
counters (see :mod:`fliss.sim.scene` for the model).
"""

import math
from dataclasses import dataclass

import numpy as np

from ...hdl.event import PULSE_BITS, TDC_LSB_S
from ..models import delay as _delay
from ..models import scheduler as _scheduler
from ...protocol.events import EVENT_DTYPE
from .description import COUNTERS, FWHM_PER_SIGMA, TDC_CODES, Scene
from . import few
from .avalanches import DetectorPath
from .detection import non_paralysable, spans
from .generation import QUIET_CYCLES, PhotonGeneration
from .pulses import EdgeBuffer, EdgeSchedule, PulseTrain, fed_edges


__all__ = ["Chunk", "Simulation", "spans", "non_paralysable"]


_GENERATED, _OUTSIDE, _DEAD, _OVERWRITTEN, _RECORDED = range(len(COUNTERS))

_NO_EVENTS = np.zeros(0, dtype=EVENT_DTYPE)
_NO_EVENTS.flags.writeable = False


@dataclass
class Chunk:
    """What one :meth:`Simulation.step` produced.

    Attributes
    ----------
    first_pulse : int
        Index of its first laser cycle.
    start_cycles : numpy.ndarray
        TDC start (laser rising edge) of each of its cycles, in clock cycles.
    events : numpy.ndarray
        ``EVENT_DTYPE`` events, in time order.
    counts : numpy.ndarray
        ``(sources, len(COUNTERS))`` photon counters of the chunk.
    """

    first_pulse: int
    start_cycles: np.ndarray
    events: np.ndarray
    counts: np.ndarray

    @property
    def cycles(self):
        return len(self.start_cycles)


class Simulation(DetectorPath, PhotonGeneration):
    """The scene, laser cycle after laser cycle, in chunks.

    Parameters
    ----------
    scene : Scene
    seed : int or numpy.random.SeedSequence or None
        Seed of the photon statistics (the delay sequences have their own seeds in the settings).
    chunk_cycles : int
        Laser cycles per chunk: memory is proportional to it.
    external_starts : bool
        The victim's TDC starts do not come from the reference scheduler (``scene.victim``) but
        are given with :meth:`feed`, for instance as a simulated gateware emits them; a laser
        cycle is simulated once the start of the next one is known.
    external_aggressors : bool
        The aggressors' laser triggers are given with :meth:`feed_aggressor`: each aggressor is
        then a pulse ``offset_s + tof`` after each trigger edge, and its own period and delay
        settings are not used.
    """

    #: Steps with at most this many photons are resolved in plain Python (:mod:`.few`), the
    #: others with numpy; the results are the same.
    few_photons = few.FEW_PHOTONS

    #: Steps of fed starts over at most this many laser cycles make their photons in plain
    #: Python, and those without photons stop there (:mod:`.generation`); the results are the
    #: same (0: every step with numpy).
    quiet_cycles = QUIET_CYCLES

    def __init__(self, scene, *, seed=None, chunk_cycles=1 << 16, external_starts=False,
                 external_aggressors=False):
        if not isinstance(scene, Scene):
            raise ValueError(f"Expected a Scene, not {scene!r}")
        if isinstance(chunk_cycles, bool) or not isinstance(chunk_cycles, (int, np.integer)) \
                or chunk_cycles < 1:
            raise ValueError(f"Chunk size must be a positive number of laser cycles, "
                             f"not {chunk_cycles!r}")
        self.scene = scene
        self.chunk_cycles = int(chunk_cycles)
        self._rng = np.random.default_rng(seed)
        lsb = scene.lsb_per_cycle
        self._lsb = lsb
        self._dead = scene.dead_time_s / TDC_LSB_S
        spad = self.spad = scene.spad
        # The detector's PDP thins the scene's photons; its dark counts join the background
        # (1 and 0 by default: the same numbers as before)
        dark = float(spad.dark_rates(1)[0]) if spad.dark_count_hz or spad.hot_dark_count_hz \
            else 0.0
        self._background = (scene.background_hz * spad.pdp + dark) * TDC_LSB_S
        self._background_shares = None     # a pixel array's shares when its rates differ
        self._effects = spad.avalanche_effects     # steps through DetectorPath
        jitter = scene.jitter_fwhm_s / FWHM_PER_SIGMA / TDC_LSB_S
        self.external_starts = bool(external_starts)
        if self.external_starts and scene.fine_step != 1:
            raise ValueError("Fed TDC starts are whole clock cycles: a scene with a fine delay "
                             "step takes its starts from the scheduler model")
        self._starts = EdgeBuffer(None if self.external_starts else
                               EdgeSchedule(scene.victim, self.chunk_cycles + 1,
                                            fine_step=scene.fine_step))
        # Pulsed sources: (pulses, mean detections, sigma in LSBs, per-pulse jitter in LSBs)
        self._pulsed = []
        sigma = math.hypot(scene.fwhm_s / FWHM_PER_SIGMA / TDC_LSB_S, jitter)
        # Fed from outside, the victim fires with some of the starts only (see `feed`).
        self._fired = EdgeBuffer(None) if self.external_starts else self._starts
        self._signal = PulseTrain(self._fired, scale=lsb, shift=scene.tof_s / TDC_LSB_S,
                               guess=self.chunk_cycles + 2, trim=self.external_starts)
        self._pulsed.append((self._signal, scene.detections_per_pulse * spad.pdp, sigma, 0.0))
        self.external_aggressors = bool(external_aggressors)
        self._aggressor_edges = []
        for aggressor in scene.aggressors:
            tof = scene.tof_s if aggressor.tof_s is None else aggressor.tof_s
            shift = (aggressor.offset_s + tof) / TDC_LSB_S
            # Its own oscillator: one of its cycles lasts 1 / (1 + ppm 1e-6) victim cycles
            own = lsb / (1.0 + aggressor.ppm * 1e-6)
            if self.external_aggressors:
                edges = EdgeBuffer(None)
                self._aggressor_edges.append(edges)
                pulses = PulseTrain(edges, scale=own, shift=shift, guess=64)
            elif aggressor.has_delays:
                pulses = PulseTrain(EdgeBuffer(EdgeSchedule(aggressor.settings(), self.chunk_cycles)),
                                 scale=own, shift=shift, guess=self.chunk_cycles + 2)
            else:
                pulses = PulseTrain(shift=shift + (1 + _scheduler.LATENCY) * own,
                                 step=float(aggressor.period_cycles) * own)
            sigma = math.hypot(aggressor.fwhm_s / FWHM_PER_SIGMA / TDC_LSB_S, jitter)
            self._pulsed.append((pulses, aggressor.detections_per_pulse * spad.pdp, sigma,
                                 aggressor.jitter_s / TDC_LSB_S))
        self._sources = len(scene.sources)
        # Windows and dead times of consecutive pulses never meet when the shortest time between
        # two TDC starts is longer than both: a faster path that needs no per-cycle arrays.
        victim = scene.victim
        shortest = victim.period - (_delay.max_delay(victim.mode, length=victim.length,
                                                     mask_width=victim.mask_width)
                                    / scene.fine_step if victim.grid else 0)
        self._separated = shortest * lsb > TDC_CODES + self._dead and not self.external_starts
        self.pulse = 0
        self._previous_end = -math.inf
        self._last_detection = -math.inf
        self._carry_times = np.zeros(0)
        self._carry_sources = np.zeros(0, dtype=np.int8)
        # A pixel array (see PixelSimulation) sets its number of pixels, the pixels of the
        # photons carried over and, per pulsed source, how its photons spread over the pixels.
        self._pixel_count = None
        self._carry_pixels = None
        self._per_pixel = None
        self._hits = None               # see _draws
        self._quiet_sources = None      # see _quiet
        self._plain_shares = None       # the pixels' shares and arrival times, as lists
        self._no_counts = None          # the counters of a step without photons (read-only)
        #: Photon counters since the start, ``(sources, len(COUNTERS))``.
        self.counts = np.zeros((self._sources, len(COUNTERS)), dtype=np.int64)

    @property
    def next_start_cycle(self):
        """TDC start cycle of the next laser cycle to simulate (``None`` if not fed yet); a
        ``float`` with a fine delay step."""
        known = self._starts.get(self.pulse, self.pulse + 1)
        return known[0].item() if len(known) else None

    def feed(self, start_cycles, *, fired=True):
        """Give the next TDC starts, in clock cycles, with ``external_starts``: integers (an
        array, or one integer), increasing, after every start given before. With ``fired``, the
        victim laser fires with them (its echo follows); without, they only close the previous
        TDC window."""
        if not self.external_starts:
            raise ValueError("This simulation takes its TDC starts from the scheduler model; "
                             "create it with external_starts=True to feed them")
        values = fed_edges(start_cycles, self._starts.last, "TDC starts", "feed")
        self._starts.feed(values)
        if fired:
            self._fired.feed(values)

    def feed_aggressor(self, index, edge_cycles):
        """Give the next rising edges of aggressor ``index``'s laser trigger, in clock cycles,
        with ``external_aggressors``: integers (an array, or one integer), increasing, after
        every edge given before. Give each edge before :meth:`step` simulates the laser cycles
        its photons fall in: photons of an edge given later are not simulated."""
        if not self.external_aggressors:
            raise ValueError("This simulation takes its aggressors from their settings; create "
                             "it with external_aggressors=True to feed their triggers")
        if not isinstance(index, (int, np.integer)) or not 0 <= index < len(self._aggressor_edges):
            raise ValueError(f"Aggressor index must be from 0 to "
                             f"{len(self._aggressor_edges) - 1}, not {index!r}")
        edges = self._aggressor_edges[index]
        edges.feed(fed_edges(edge_cycles, edges.last, "Aggressor trigger edges",
                             "feed_aggressor"))

    def step(self, max_cycles=None, *, until_cycle=None):
        """Simulate the next laser cycles: at most ``max_cycles`` (default: one chunk), and only
        those whose TDC start is before clock cycle ``until_cycle``. Returns a :class:`Chunk`."""
        if self._effects:
            return self._detector_step(max_cycles, until_cycle)
        prepared = self._prepare(max_cycles, until_cycle)
        if isinstance(prepared, Chunk):
            return prepared
        cycles, count, (starts, span_starts, ends, boundary), (times, sources, _) = prepared
        later = times >= boundary
        if later.any():
            self._carry_times, self._carry_sources = times[later], sources[later]
            now = ~later
            times, sources = times[now], sources[now]
        else:
            self._carry_times, self._carry_sources = times[:0], sources[:0]
        if len(times) <= self.few_photons:
            return self._few(times, sources, cycles, count, starts, span_starts, ends)
        order = np.argsort(times)
        times = times[order]
        sources = sources[order]

        # Which span each photon is in: the TDC window of `span`, or the dead time before it
        span, in_span, in_window = spans(times, starts, span_starts, ends, self._dead,
                                          self._separated)

        # Detection: which span, dead time, single-hit TDC
        counts = np.zeros_like(self.counts)
        counts[:, _GENERATED] = np.bincount(sources, minlength=self._sources)
        span_times = times[in_span]
        detected = non_paralysable(span_times, self._dead, self._last_detection)
        if detected.any():
            self._last_detection = float(span_times[detected][-1])
        window = in_window[in_span]
        candidate = window & detected
        picked = np.flatnonzero(in_span)[candidate]
        cycle = span[picked]
        if self.scene.keep == "last":
            keep = np.ones(len(cycle), dtype=bool)
            keep[:-1] = cycle[1:] != cycle[:-1]
        else:
            keep = np.ones(len(cycle), dtype=bool)
            keep[1:] = cycle[1:] != cycle[:-1]
        recorded = picked[keep]
        counts[:, _OUTSIDE] = np.bincount(sources[~in_window], minlength=self._sources)
        counts[:, _DEAD] = np.bincount(sources[np.flatnonzero(in_span)[window & ~detected]],
                                       minlength=self._sources)
        counts[:, _OVERWRITTEN] = np.bincount(sources[picked[~keep]], minlength=self._sources)
        counts[:, _RECORDED] = np.bincount(sources[recorded], minlength=self._sources)

        events = np.zeros(len(recorded), dtype=EVENT_DTYPE)
        cycle = span[recorded]
        stamps = np.floor(times[recorded] - starts[cycle]).astype(np.int64)
        events["timestamp"] = np.minimum(stamps, TDC_CODES - 1)
        events["address"] = self.scene.address
        events["pulse"] = (self.pulse + cycle) & ((1 << PULSE_BITS) - 1)

        return self._advance(cycles, count, starts, ends, events, counts)

    def _tdc(self, fires, span, pixel, times):
        """The detections the TDC keeps of ``fires`` (indices in time order): the last (first)
        of each window, and their collision flags (0)."""
        cycle = span[fires]
        keep = np.ones(len(cycle), dtype=bool)
        if self.scene.keep == "last":
            keep[:-1] = cycle[1:] != cycle[:-1]
        else:
            keep[1:] = cycle[1:] != cycle[:-1]
        return fires[keep], np.zeros(int(keep.sum()), dtype=np.uint8)

    def _empty_chunk(self, start_cycles):
        """The chunk of a step without photons (its counters read-only)."""
        if self._no_counts is None:
            self._no_counts = np.zeros_like(self.counts)
            self._no_counts.flags.writeable = False
        return Chunk(self.pulse, start_cycles, _NO_EVENTS, self._no_counts)

    def _advance(self, cycles, count, starts, ends, events, counts):
        """The chunk of a step over ``count`` laser cycles; moves on past them."""
        chunk = Chunk(self.pulse, cycles[:count].copy(), events, counts)
        self.pulse += count
        self._starts.trim(self.pulse if self.external_starts else
                          min(self.pulse, self._signal.next_index))
        self._previous_end = float(starts[-1] + TDC_CODES if self._separated else ends[-1])
        self.counts += counts
        return chunk

    def _few(self, times, sources, cycles, count, starts, span_starts, ends):
        """The rest of :meth:`step` for a few photons (``times`` not sorted), in plain Python
        (:func:`~fliss.sim.scene.few.detect`: the same results)."""
        if not len(times):
            return self._advance(cycles, count, starts, ends, np.zeros(0, dtype=EVENT_DTYPE),
                                 np.zeros_like(self.counts))
        times, sources = times.tolist(), sources.tolist()
        order = sorted(range(len(times)), key=times.__getitem__)
        begins = starts.tolist()
        windows = (begins, None, None, True) if self._separated else \
            (begins, span_starts.tolist(), ends.tolist(), False)
        recorded, counts, last = few.detect([times[i] for i in order],
                                            [sources[i] for i in order], windows, self._dead,
                                            self._last_detection, self.scene.keep == "last",
                                            self._sources)
        self._last_detection = last
        events = np.zeros(len(recorded), dtype=EVENT_DTYPE)
        if recorded:
            events["timestamp"] = [few.timestamp(time, begins[span]) for span, time in recorded]
            events["address"] = self.scene.address
            events["pulse"] = [(self.pulse + span) & ((1 << PULSE_BITS) - 1)
                               for span, _ in recorded]
        return self._advance(cycles, count, starts, ends, events,
                             np.array(counts, dtype=np.int64))

    def chunks(self, cycles):
        """Chunks covering the next ``cycles`` laser cycles (fewer if the TDC starts fed so far
        run out first)."""
        remaining = int(cycles)
        while remaining > 0:
            chunk = self.step(min(remaining, self.chunk_cycles))
            if chunk.cycles == 0:
                return
            remaining -= chunk.cycles
            yield chunk
