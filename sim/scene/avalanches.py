"""The detector path of the scene simulator: a paralysable dead time, the diffusion tail,
afterpulses and crosstalk (the :class:`~fliss.sim.scene.detector.Detector`'s effects), for
one pixel or a pixel array, vectorised.

A simulation whose detector has any of them steps through :meth:`DetectorPath._detector_step`
instead of its plain path (the PDP and the dark counts only change the sources' means, and
need no path of their own). A step:

1. makes its photons as the plain path does (the same draws), and delays a ``tail_fraction``
   of the new photons of the pulsed sources by an exponential of mean ``tail_s``;
2. resolves the avalanches (:meth:`Avalanches.resolve`): which photons start an avalanche
   (each pixel's SPAD, its dead time paralysable or not), then, for every avalanche, its
   afterpulse and its neighbours' crosstalk, as new photons that can start avalanches of
   their own and block others. A child comes after its parent, so the resolution is causal:
   each pass resolves the photons with the children of the avalanches found so far, and the
   earliest photon whose fate changed moves later from pass to pass; the passes stop when
   nothing changes (every avalanche has its children, every child's parent is an avalanche);
3. keeps one detection per TDC window (per pixel, or for the column) as the plain path does.

Children later than the step's boundary are carried to the next step, like every photon.
Each effect has its own generator (spawned from the simulation's after the sources' ones), so
the sources' draws are those of the plain path; the children's draws follow the order in
which the passes find the avalanches, so they depend on how the run is cut into steps (the
statistics do not). Closed-loop steps of a few photons take this path too, with numpy.
"""

import numpy as np

from ...hdl.event import PULSE_BITS, TDC_LSB_S
from ...protocol.events import EVENT_DTYPE
from .description import COUNTERS, TDC_CODES
from .detection import non_paralysable, spans
from .draws import Ahead
from .few_avalanches import counters, resolve_few, tdc_few


__all__ = ["Avalanches", "DetectorPath", "pixel_avalanches"]


_GENERATED, _OUTSIDE, _DEAD, _OVERWRITTEN, _RECORDED = range(len(COUNTERS))


def _uniforms(rng, count):
    return rng.random(count)


def _normals(rng, count):
    return rng.standard_normal(count)


def pixel_avalanches(times, pixel, last, dead, paralysable):
    """``(avalanche, counted)`` of the photons at ``times`` (sorted) of pixels ``pixel``, each
    pixel's last avalanche before them at ``last[pixel]``: non-paralysable, a photon less than
    ``dead`` after the last avalanche of its pixel does nothing (both ``False``); paralysable,
    every photon is an avalanche, counted when ``dead`` or more after the previous one."""
    count = len(times)
    if count == 0 or dead <= 0:
        return np.ones(count, dtype=bool), np.ones(count, dtype=bool)
    if paralysable:
        order = np.lexsort((np.arange(count), pixel))        # by pixel, then in time order
        ordered, owner = times[order], pixel[order]
        first = np.ones(count, dtype=bool)
        first[1:] = owner[1:] != owner[:-1]
        previous = np.empty(count)
        previous[1:] = ordered[:-1]
        previous[first] = last[owner[first]]
        counted = np.empty(count, dtype=bool)
        counted[order] = ordered - previous >= dead
        return np.ones(count, dtype=bool), counted
    # Non-paralysable: each pixel's photons on one axis, one block per pixel starting with its
    # last avalanche, blocks more than a dead time apart (as PixelSimulation._detect)
    pixels = len(last)
    origin = float(times[0])
    stride = float(times[-1] - origin) + 4.0 * dead + 1.0
    keyed = np.concatenate((np.maximum(last - origin, -2.0 * dead) + np.arange(pixels) * stride,
                            (times - origin) + pixel * stride))
    order = np.argsort(keyed, kind="stable")
    result = np.empty(len(keyed), dtype=bool)
    result[order] = non_paralysable(keyed[order], dead, -np.inf)
    counted = result[pixels:]
    return counted, counted


class Avalanches:
    """The detector's effects on a step's photons (see the module): its draws and their
    resolution. ``rngs``: four generators (tail, afterpulses, crosstalk, crosstalk delays);
    ``neighbours``: the array's :meth:`~fliss.sim.scene.pixels.PixelArray.neighbours`
    (``None`` for one pixel); ``first_source``: the index of the first child source."""

    def __init__(self, spad, rngs, neighbours, first_source):
        self.dead = spad.dead_time_s / TDC_LSB_S
        self.paralysable = bool(spad.paralysable)
        self._tail = (spad.tail_fraction, spad.tail_s / TDC_LSB_S)
        self._sigma = spad.sigma_s / TDC_LSB_S
        tail, after, cross, delays = rngs
        self._tail_draws = Ahead(tail, _uniforms)
        self._after_draws = Ahead(after, _uniforms)
        self._cross_draws = Ahead(cross, _uniforms)
        self._cross_delays = Ahead(delays, _normals)
        source = first_source
        self._after = None
        if spad.afterpulsing:
            self._after = (spad.afterpulse_probability, np.cumsum(spad.afterpulse_weights),
                           np.array(spad.afterpulse_s) / TDC_LSB_S, source)
            source += 1
        self._cross = None
        if spad.crosstalk and neighbours is not None:
            targets = np.concatenate(neighbours, axis=1)
            chance = np.repeat([spad.crosstalk_orthogonal, spad.crosstalk_diagonal], 4)
            self._cross = (targets, np.where(targets >= 0, chance, 0.0), source)

    def tail(self, times, sources, first):
        """``times`` with the diffusion tail on the photons of the pulsed sources from index
        ``first`` on (those before are carried over and have theirs)."""
        fraction, mean = self._tail
        if fraction <= 0 or len(times) <= first:
            return times
        index = first + np.flatnonzero(sources[first:] != 1)
        if not len(index):
            return times
        draws = self._tail_draws.array(2 * len(index))
        late = draws[:len(index)] < fraction
        times = times.copy()
        times[index[late]] -= mean * np.log1p(-draws[len(index):][late])
        return times

    def _children(self, times, pixel, parents):
        """The afterpulses and crosstalk of the avalanches ``parents`` (indices):
        ``(times, sources, pixels, parents)`` of the new photons."""
        pieces = []
        if self._after is not None:
            probability, cumulative, means, source = self._after
            draws = self._after_draws.array(3 * len(parents)).reshape(-1, 3)
            has = draws[:, 0] < probability
            kind = np.minimum(np.searchsorted(cumulative, draws[has, 1], side="right"),
                              len(means) - 1)
            owner = parents[has]
            pieces.append((times[owner] - means[kind] * np.log1p(-draws[has, 2]),
                           np.full(len(owner), source, dtype=np.int8), pixel[owner], owner))
        if self._cross is not None:
            targets, chance, source = self._cross
            draws = self._cross_draws.array(8 * len(parents)).reshape(-1, 8)
            row, column = np.nonzero(draws < chance[pixel[parents]])
            owner = parents[row]
            delay = self._sigma * np.abs(self._cross_delays.array(len(owner)))
            pieces.append((times[owner] + delay, np.full(len(owner), source, dtype=np.int8),
                           targets[pixel[owner], column].astype(pixel.dtype), owner))
        return [np.concatenate(part) for part in zip(*pieces)]

    def resolve(self, times, sources, pixel, locate, last, boundary):
        """Resolve a step's photons (``times`` sorted, all before ``boundary``; ``locate``
        gives ``(span, in_span, in_window)`` of sorted times; ``last``: each pixel's last
        avalanche, updated). Returns the step's photons with their children, in time order,
        ``(times, sources, pixel, span, in_window, counted)``, and the children at or after
        the boundary, ``(times, sources, pixel)``."""
        parent = np.full(len(times), -1, dtype=np.int64)
        depth = np.zeros(len(times), dtype=np.int64)
        expanded = np.zeros(len(times), dtype=bool)
        active = np.ones(len(times), dtype=bool)
        initial = last.copy()
        while True:
            index = np.flatnonzero(active & (times < boundary))
            index = index[np.argsort(times[index], kind="stable")]
            step_times = times[index]
            span, in_span, in_window = locate(step_times)
            spanned = np.flatnonzero(in_span)
            avalanche, counted = pixel_avalanches(step_times[spanned], pixel[index[spanned]],
                                                  initial, self.dead, self.paralysable)
            fired = np.zeros(len(times), dtype=bool)
            fired[index[spanned[avalanche]]] = True
            new = np.flatnonzero(fired & ~expanded)
            if len(new) and (self._after is not None or self._cross is not None):
                expanded[new] = True
                more = self._children(times, pixel, new)
                if len(more[0]):
                    times = np.concatenate((times, more[0]))
                    sources = np.concatenate((sources, more[1]))
                    pixel = np.concatenate((pixel, more[2]))
                    parent = np.concatenate((parent, more[3]))
                    depth = np.concatenate((depth, depth[more[3]] + 1))
                    expanded = np.concatenate((expanded, np.zeros(len(more[0]), dtype=bool)))
                    fired = np.concatenate((fired, np.zeros(len(more[0]), dtype=bool)))
            # A child is there when its parent is and started an avalanche
            now = np.ones(len(times), dtype=bool)
            for level in range(1, int(depth.max(initial=0)) + 1):
                at = np.flatnonzero(depth == level)
                now[at] = now[parent[at]] & fired[parent[at]]
            if len(now) == len(active) and np.array_equal(now, active):
                break
            active = now
        hits = index[spanned[avalanche]]
        if len(hits):
            np.maximum.at(last, pixel[hits], times[hits])
        kept = np.zeros(len(step_times), dtype=bool)
        kept[spanned[counted]] = True
        later = np.flatnonzero(active & (times >= boundary))
        return ((step_times, sources[index], pixel[index], span, in_window, kept),
                (times[later], sources[later], pixel[later]))


class DetectorPath:
    """The step of a :class:`~fliss.sim.scene.photons.Simulation` (one pixel or an array)
    whose detector has effects (see the module)."""

    _avalanches = None

    def _detector_step(self, max_cycles, until_cycle):
        if self._avalanches is None:
            self._draws()                   # the sources' generators are spawned first
            neighbours = None if self._pixel_count is None else self.pixels.neighbours()
            self._avalanches = Avalanches(self.spad, self._rng.spawn(4), neighbours,
                                          2 + len(self.scene.aggressors))
        carried = len(self._carry_times)
        prepared = self._prepare(max_cycles, until_cycle)
        if not isinstance(prepared, tuple):
            return prepared
        cycles, count, (starts, span_starts, ends, boundary), (times, sources, pixel) = prepared
        array = self._pixel_count is not None
        if not self._separated and len(times) <= self.few_photons:
            return self._few_detector_step(cycles, count, (starts, span_starts, ends, boundary),
                                           (times, sources, pixel), carried)
        if not array:
            pixel = np.zeros(len(times), dtype=np.int16)
        times = self._avalanches.tail(times, sources, carried)
        later = times >= boundary
        now = np.flatnonzero(~later)
        now = now[np.argsort(times[now], kind="stable")]
        last = self._last_detections if array else np.array([self._last_detection])

        def locate(at):
            return spans(at, starts, span_starts, ends, self._dead, self._separated)

        (times_, sources_, pixel_, span, in_window, counted), children = \
            self._avalanches.resolve(times[now], sources[now], pixel[now], locate, last,
                                     boundary)
        if not array:
            self._last_detection = float(last[0])
        self._carry_times = np.concatenate((times[later], children[0]))
        self._carry_sources = np.concatenate((sources[later], children[1]))
        if array:
            self._carry_pixels = np.concatenate((pixel[later], children[2]))
        fires = np.flatnonzero(in_window & counted)
        what = np.full(len(times_), _OUTSIDE, dtype=np.int64)
        what[in_window & ~counted] = _DEAD
        what[fires] = _OVERWRITTEN
        recorded, collision = self._tdc(fires, span, pixel_, times_)
        what[recorded] = _RECORDED
        events = np.zeros(len(recorded), dtype=EVENT_DTYPE)
        cycle = span[recorded]
        stamps = np.floor(times_[recorded] - starts[cycle]).astype(np.int64)
        events["timestamp"] = np.minimum(stamps, TDC_CODES - 1)
        events["address"] = self._addresses[pixel_[recorded]] if array else self.scene.address
        events["collision"] = collision
        events["pulse"] = (self.pulse + cycle) & ((1 << PULSE_BITS) - 1)
        if array:
            return self._advance_pixels(cycles, count, starts, ends, events, pixel_, sources_,
                                        what)
        counters = len(COUNTERS)
        counts = np.bincount(sources_.astype(np.int64) * counters + what,
                             minlength=self._sources * counters).reshape(self._sources,
                                                                         counters)
        counts[:, _GENERATED] = counts.sum(axis=1)
        return self._advance(cycles, count, starts, ends, events, counts)


    def _few_detector_step(self, cycles, count, windows, photons, carried):
        """The rest of :meth:`_detector_step` for a few photons, in plain Python
        (:mod:`.few_avalanches`: the same results)."""
        starts, span_starts, ends, boundary = windows
        array = self._pixel_count is not None
        times, sources, pixel = photons
        begins = starts.tolist()
        last = self._last_detections.tolist() if array else [self._last_detection]
        resolved, carry = resolve_few(
            self._avalanches, (times.tolist(), sources.tolist(),
                               pixel.tolist() if array else [0] * len(times)),
            carried, (begins, span_starts.tolist(), ends.tolist()), last, boundary)
        self._carry_times = np.array(carry[0], dtype=np.float64)
        self._carry_sources = np.array(carry[1], dtype=np.int8)
        options = (self.scene.keep == "last", self._column, self._collision) if array else \
            (self.scene.keep == "last", True, 0.0)
        recorded, what = tdc_few(resolved, begins, options, self._sources)
        events = np.zeros(len(recorded), dtype=EVENT_DTYPE)
        if recorded:
            span, stamps, pixels, collisions = zip(*recorded)
            events["timestamp"] = stamps
            events["address"] = self._addresses[list(pixels)] if array else self.scene.address
            events["collision"] = collisions
            events["pulse"] = [(self.pulse + index) & ((1 << PULSE_BITS) - 1) for index in span]
        if array:
            self._last_detections[:] = last
            self._carry_pixels = np.array(carry[2], dtype=np.int16)
            return self._advance_pixels(cycles, count, starts, ends, events,
                                        np.array(resolved[2], dtype=np.int16),
                                        np.array(resolved[1], dtype=np.int8),
                                        np.array(what, dtype=np.int64))
        self._last_detection = float(last[0])
        return self._advance(cycles, count, starts, ends, events,
                             np.array(counters(resolved[1], what, self._sources),
                                      dtype=np.int64))
