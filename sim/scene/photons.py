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
from .description import COUNTERS, FWHM_PER_SIGMA, TDC_CODES, TRUNCATION_SIGMAS, Scene
from . import few
from .detection import non_paralysable, spans
from .draws import Hits
from .pulses import EdgeBuffer, EdgeSchedule, PulseTrain, fed_edges


__all__ = ["Chunk", "Simulation", "spans", "non_paralysable"]


_GENERATED, _OUTSIDE, _DEAD, _OVERWRITTEN, _RECORDED = range(len(COUNTERS))


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


_LABELS = {}

#: Largest number of laser cycles a step without photons takes in plain Python
#: (:meth:`Simulation._quiet`; closed loop steps one to three).
QUIET_CYCLES = 8

_NO_EVENTS = np.zeros(0, dtype=EVENT_DTYPE)
_NO_EVENTS.flags.writeable = False


def _labels(source, number):
    """``number`` times the source index ``source`` (``int8``; a read-only view of a
    constant when short: a step's few photons cost no new array)."""
    if number > 4096:
        return np.full(number, source, dtype=np.int8)
    if source not in _LABELS:
        _LABELS[source] = np.full(4096, source, dtype=np.int8)
        _LABELS[source].flags.writeable = False
    return _LABELS[source][:number]


class Simulation:
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

    #: Steps of fed starts over at most this many laser cycles and without photons take a
    #: shorter path in plain Python (:meth:`_quiet`); the results are the same.
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
        self._background = scene.background_hz * TDC_LSB_S
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
        self._pulsed.append((self._signal, scene.detections_per_pulse, sigma, 0.0))
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
            self._pulsed.append((pulses, aggressor.detections_per_pulse, sigma,
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

    def _draws(self):
        """Per pulsed source, then for the background: its Poisson counts drawn ahead
        (:class:`~fliss.sim.scene.draws.Hits`, per pulse or per span; ``None`` when its mean is
        0) and the generator of the rest of its photons' draws. Made at the first step, when a
        pixel array has set its sources' means."""
        if self._hits is None:
            array = self._pixel_count
            generators = iter(self._rng.spawn(2 * len(self._pulsed) + 2))
            self._hits = []
            for index, (_, mean, _, _) in enumerate(self._pulsed):
                if array is not None:
                    mean = self._per_pixel[index][0]
                counts, rest = next(generators), next(generators)
                self._hits.append((Hits(counts, mean) if mean else None, rest))
            # Background: a Poisson number per span of the longest length a span can have,
            # then thinned to each span's own length
            mean = self._background * (TDC_CODES + self._dead) * (array or 1)
            counts, rest = next(generators), next(generators)
            self._hits.append((Hits(counts, mean) if mean > 0 else None, rest))
        return self._hits

    def _reach(self, index):
        """``(spread, lowest)`` of source ``index``: its pulses before :meth:`_limit` of a
        ``boundary`` (``boundary + spread + 1.0 - lowest``) have photons before it."""
        _, _, sigma, wander = self._pulsed[index]
        lowest = 0.0 if self._pixel_count is None else self._per_pixel[index][2]
        return TRUNCATION_SIGMAS * (sigma + wander), lowest

    def _limit(self, boundary, index):
        spread, lowest = self._reach(index)
        return boundary + spread + 1.0 - lowest

    def _photons(self, boundary, count, starts, span_starts, ends):
        """Photons up to ``boundary`` (and of the pulses near it, after it): carried over, from
        each pulsed source, and background in the ``count`` spans; ``(times, sources, pixels)``,
        not sorted. ``pixels`` is ``None`` but for a pixel array, whose pulsed sources give each
        pixel its own mean detections and arrival time (``_per_pixel``) and whose background falls
        on every pixel alike."""
        array = self._pixel_count
        draws = self._draws()
        times, sources, owners = [self._carry_times], [self._carry_sources], [self._carry_pixels]
        for index, (pulses, _, sigma, wander) in enumerate(self._pulsed):
            source = index if index == 0 else index + 1
            centres = pulses.until(self._limit(boundary, index))
            hits, rng = draws[index]
            if hits is None or len(centres) == 0:
                continue
            # Each pulse's Poisson number of photons (for a pixel array, of the array's
            # photons, shared out by the pixels' means: the same law as each pixel's own)
            pulse, number = hits.take(len(centres))
            if not len(pulse):
                continue
            centres = centres[pulse]
            if wander > 0:
                centres = centres + wander * rng.standard_normal(len(centres)).clip(
                    -TRUNCATION_SIGMAS, TRUNCATION_SIGMAS)
            arrivals = np.repeat(centres, number)
            number = len(arrivals)
            if array is not None:
                _, extra, _, shares = self._per_pixel[index]
                pixel = np.searchsorted(shares, rng.random(number), side="right")
                pixel = np.minimum(pixel, array - 1).astype(np.int16)
                owners.append(pixel)
                arrivals = arrivals + extra[pixel]
            spread = rng.standard_normal(number).clip(-TRUNCATION_SIGMAS, TRUNCATION_SIGMAS)
            times.append(arrivals + sigma * spread)
            sources.append(_labels(source, number))
        hits, rng = draws[-1]
        span, number = hits.take(count) if hits is not None else ((), ())
        if len(span):
            # A Poisson process on each span: drawn on spans all as long as the longest a span
            # can be (its window and the dead time before), thinned to each span's length.
            span = np.repeat(span, number)
            number = len(span)
            offset = rng.uniform(0.0, TDC_CODES + self._dead, number)
            if array is not None:
                pixel = rng.integers(0, array, number).astype(np.int16)
            if self._separated:
                times.append(starts[span] + (offset - self._dead))
            else:
                inside = offset < (ends - span_starts)[span]
                times.append(span_starts[span[inside]] + offset[inside])
                number = int(inside.sum())
                if array is not None:
                    pixel = pixel[inside]
            sources.append(_labels(1, number))
            if array is not None:
                owners.append(pixel)
        return self._gathered(times, sources, owners)

    def _quiet(self, max_cycles, until_cycle):
        """The next step (fed starts, a few laser cycles) when it has no photon, in plain
        Python: nothing carried over, and every pulse and span it covers drawn with none;
        ``None`` otherwise (:meth:`step` then simulates it)."""
        if len(self._carry_times):
            return None
        max_cycles = self.chunk_cycles if max_cycles is None else int(max_cycles)
        most = self.quiet_cycles
        cycles = self._starts.values(self.pulse, self.pulse + min(max_cycles, most) + 1)
        count = min(max_cycles, len(cycles) - 1)
        if until_cycle is not None:
            count = min(count, sum(cycle < until_cycle for cycle in cycles))
        if count <= 0 or (count == most and max_cycles > most):
            return None
        lsb, dead = self._lsb, self._dead       # the windows, as _windows makes them
        edges = [cycle * lsb for cycle in cycles[:count + 1]]
        if self._separated:
            boundary = edges[-1] - dead
            previous_end = edges[-2] + TDC_CODES
        else:
            previous_end = min(edges[-2] + TDC_CODES, edges[-1])
            boundary = max(edges[-1] - dead, previous_end)
        if self._quiet_sources is None:
            draws = self._draws()
            self._quiet_sources = [(pulses, draws[index][0], *self._reach(index))
                                   for index, (pulses, *_) in enumerate(self._pulsed)]
        handed = []
        for pulses, hits, spread, lowest in self._quiet_sources:
            number = pulses.count_until(boundary + spread + 1.0 - lowest)
            if number and hits is not None and not hits.quiet(number):
                return None
            handed.append(number)
        background = self._hits[-1][0]
        if background is not None and not background.quiet(count):
            return None
        for (pulses, hits, *_), number in zip(self._quiet_sources, handed):
            pulses.skip(number)
            if hits is not None:
                hits.skip(number)
        if background is not None:
            background.skip(count)
        chunk = self._empty_chunk(np.array(cycles[:count], dtype=np.int64))
        self.pulse += count
        self._starts.trim(self.pulse)
        self._previous_end = previous_end
        return chunk

    def _empty_chunk(self, start_cycles):
        if self._no_counts is None:
            self._no_counts = np.zeros_like(self.counts)
            self._no_counts.flags.writeable = False
        return Chunk(self.pulse, start_cycles, _NO_EVENTS, self._no_counts)

    def _gathered(self, times, sources, owners):
        if len(times) == 1:
            return times[0], sources[0], owners[0]
        return (np.concatenate(times), np.concatenate(sources),
                None if self._pixel_count is None else np.concatenate(owners))

    def _cycles(self, max_cycles, until_cycle):
        """The TDC start cycles from the next laser cycle on, and how many of them the next step
        simulates (at most ``max_cycles``, those before ``until_cycle``)."""
        max_cycles = self.chunk_cycles if max_cycles is None else int(max_cycles)
        cycles = self._starts.get(self.pulse, self.pulse + max_cycles + 1)
        count = max(min(max_cycles, len(cycles) - 1), 0)   # the next start must be known
        if until_cycle is not None:
            count = int(np.searchsorted(cycles[:count], until_cycle, side="left"))
        return cycles, count

    def _windows(self, cycles, count):
        """Times of the step's ``count`` TDC starts, of its spans (``None`` when they never
        touch) and of their ends (the same), and the time from which photons belong to the
        next step."""
        edges = cycles[:count + 1] * self._lsb
        starts = edges[:-1]
        ends = span_starts = None
        if self._separated:
            # Every span is [start - dead, start + 2**13) and they never touch.
            boundary = edges[-1] - self._dead
        else:
            ends = np.minimum(starts + TDC_CODES, edges[1:])
            span_starts = np.maximum(starts - self._dead,
                                     np.concatenate(([self._previous_end], ends[:-1])))
            boundary = max(edges[-1] - self._dead, ends[-1])
        return starts, span_starts, ends, boundary

    def step(self, max_cycles=None, *, until_cycle=None):
        """Simulate the next laser cycles: at most ``max_cycles`` (default: one chunk), and only
        those whose TDC start is before clock cycle ``until_cycle``. Returns a :class:`Chunk`."""
        if self.external_starts:
            quiet = self._quiet(max_cycles, until_cycle)
            if quiet is not None:
                return quiet
        cycles, count = self._cycles(max_cycles, until_cycle)
        if count == 0:
            return Chunk(self.pulse, cycles[:0].copy(), np.zeros(0, dtype=EVENT_DTYPE),
                         np.zeros_like(self.counts))
        starts, span_starts, ends, boundary = self._windows(cycles, count)

        times, sources, _ = self._photons(boundary, count, starts, span_starts, ends)
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
