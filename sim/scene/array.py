"""Photon generation and detection for a pixel array, all pixels at once (numpy, no loop over
pixels).

:class:`PixelSimulation` simulates a :class:`~fliss.sim.scene.description.Scene` whose
``pixels`` is a :class:`~fliss.sim.scene.pixels.PixelArray` (the model is in
:mod:`fliss.sim.scene.pixels`); it has the interface of
:class:`~fliss.sim.scene.photons.Simulation` (``step``, ``chunks``, ``feed``,
``feed_aggressor``, ``counts``) and gives :class:`PixelChunk` s, whose events carry each
pixel's address and the collision flag. :func:`simulation_for` picks the simulation a scene
needs.

The laser cycles, TDC windows, dead-time spans and the background drawn only where it can
matter are those of the single-pixel simulation. The SPADs are resolved all together: the
photons of each pixel, in time order, are laid one after the other on one time axis, each
pixel's block starting with its last detection so far and separated from the previous block by
more than a dead time, so one pass of the non-paralysable detector serves every pixel.
"""

from dataclasses import dataclass

import numpy as np

from ...hdl.event import PULSE_BITS, TDC_LSB_S
from ...protocol.events import EVENT_DTYPE
from .description import COUNTERS, SPEED_OF_LIGHT, TDC_CODES
from . import few
from .detection import non_paralysable, spans
from .photons import Chunk, Simulation


__all__ = ["PixelChunk", "PixelSimulation", "simulation_for"]


_GENERATED, _OUTSIDE, _DEAD, _OVERWRITTEN, _RECORDED = range(len(COUNTERS))


@dataclass
class PixelChunk(Chunk):
    """A :class:`~fliss.sim.scene.photons.Chunk` of a pixel array.

    Attributes
    ----------
    pixel_counts : numpy.ndarray
        ``(pixels, sources, len(COUNTERS))`` photon counters of each pixel (``counts`` is
        their sum). With the column sensor a photon that a SPAD detected in a window and
        another pixel's later detection overwrote counts as ``overwritten`` of its own pixel.
    """

    pixel_counts: np.ndarray = None


def simulation_for(scene, **options):
    """The simulation of ``scene``: a :class:`PixelSimulation` when it has ``pixels``, else a
    :class:`~fliss.sim.scene.photons.Simulation`; ``options`` are theirs."""
    if scene.pixels is None:
        return Simulation(scene, **options)
    return PixelSimulation(scene, **options)


def _previous_other(pixel):
    """For each position of ``pixel`` (a sequence in time order), the position of the latest
    earlier entry of another pixel, ``-1`` if none."""
    count = len(pixel)
    change = np.ones(count, dtype=bool)
    change[1:] = pixel[1:] != pixel[:-1]
    run_start = np.maximum.accumulate(np.where(change, np.arange(count), 0))
    return run_start - 1


class PixelSimulation(Simulation):
    """A pixel array, laser cycle after laser cycle, in chunks (see
    :class:`~fliss.sim.scene.photons.Simulation` for the parameters).

    Attributes
    ----------
    pixel_counts : numpy.ndarray
        ``(pixels, sources, len(COUNTERS))`` photon counters since the start.
    """

    def __init__(self, scene, **options):
        super().__init__(scene, **options)
        pixels = scene.pixels
        if pixels is None:
            raise ValueError("A PixelSimulation needs a scene with pixels (a PixelArray)")
        self.pixels = pixels
        count = len(pixels)
        self._pixel_count = count
        self._addresses = pixels.addresses
        self._column = pixels.sensor == "column"
        self._collision = pixels.collision_window_s / TDC_LSB_S
        # Per pulsed source: mean detections of the array, each pixel's arrival time after the
        # base time the source's pulse train gives (the single pixel's time of flight), the
        # earliest of those, and the pixels' cumulated shares of the detections (see
        # Simulation._photons).
        tof = 2.0 * pixels.distance_m / SPEED_OF_LIGHT / TDC_LSB_S
        own = tof - scene.tof_s / TDC_LSB_S
        pdp = self.spad.pdp
        means = [pixels.echo(scene.detections_per_pulse) * pdp]
        extras = [own]
        for aggressor in scene.aggressors:
            means.append(np.full(count, float(aggressor.detections_per_pulse) * pdp))
            extras.append(own if aggressor.tof_s is None else np.zeros(count))
        self._per_pixel = [(float(mean.sum()), extra, float(extra.min()),
                            np.cumsum(mean) / max(float(mean.sum()), 1e-300))
                           for mean, extra in zip(means, extras)]
        # The background of each pixel: the scene's (thinned by the PDP) and its dark counts
        if self.spad.dark_count_hz or self.spad.hot_dark_count_hz:
            rates = scene.background_hz * pdp + self.spad.dark_rates(count)
            if np.any(rates != rates[0]):
                self._background = float(rates.mean()) * TDC_LSB_S
                self._background_shares = np.cumsum(rates) / float(rates.sum())
            else:
                self._background = float(rates[0]) * TDC_LSB_S
        self._last_detections = np.full(count, -np.inf)
        self._carry_pixels = np.zeros(0, dtype=np.int16)
        self.pixel_counts = np.zeros((count, self._sources, len(COUNTERS)), dtype=np.int64)
        self._no_pixel_counts = None

    def _detect(self, times, pixel):
        """Which photons (``times`` in time order, of ``pixel``) the pixels' SPADs detect."""
        count = len(times)
        if count == 0 or self._dead <= 0:
            return np.ones(count, dtype=bool)
        dead = self._dead
        origin = float(times[0])
        local = times - origin
        stride = float(local[-1]) + 4.0 * dead + 1.0
        # One block per pixel: its last detection (if it still matters), then its photons.
        previous = np.maximum(self._last_detections - origin, -2.0 * dead)
        pixels = self._pixel_count
        order = np.lexsort((local, pixel))
        keyed = np.concatenate((previous + np.arange(pixels) * stride,
                                local[order] + pixel[order] * stride))
        owner = np.concatenate((np.arange(pixels), pixel[order]))
        sentinel = np.concatenate((np.ones(pixels, dtype=bool), np.zeros(count, dtype=bool)))
        block = np.lexsort((keyed, owner))
        result = non_paralysable(keyed[block], dead, -np.inf)
        detected = np.empty(count, dtype=bool)
        detected[order] = result[~sentinel[block]]
        return detected

    def step(self, max_cycles=None, *, until_cycle=None):
        """Simulate the next laser cycles (as :meth:`Simulation.step`); returns a
        :class:`PixelChunk`."""
        if self._effects:
            return self._detector_step(max_cycles, until_cycle)
        prepared = self._prepare(max_cycles, until_cycle)
        if isinstance(prepared, Chunk):
            return prepared
        cycles, count, (starts, span_starts, ends, boundary), (times, sources, pixel) = prepared
        later = times >= boundary
        self._carry_times, self._carry_sources = times[later], sources[later]
        self._carry_pixels = pixel[later]
        now = ~later
        order = np.argsort(times[now], kind="stable")
        times, sources, pixel = times[now][order], sources[now][order], pixel[now][order]
        if len(times) <= self.few_photons:
            return self._few_pixels(times, sources, pixel, cycles, count, starts, span_starts,
                                    ends)

        # Which span each photon is in: the TDC window of `span`, or the dead time before it
        span, in_span, in_window = spans(times, starts, span_starts, ends, self._dead,
                                          self._separated)

        # Detection: each pixel's dead time, then the sensor's TDCs
        spanned = np.flatnonzero(in_span)
        detected = self._detect(times[spanned], pixel[spanned])
        hits = spanned[detected]
        if len(hits):
            np.maximum.at(self._last_detections, pixel[hits], times[hits])
        window = in_window[spanned]
        fires = spanned[window & detected]          # time order
        recorded, collision = self._tdc(fires, span, pixel, times)

        what = np.full(len(times), _OUTSIDE, dtype=np.int64)
        what[spanned[window & ~detected]] = _DEAD
        what[fires] = _OVERWRITTEN
        what[recorded] = _RECORDED
        events = np.zeros(len(recorded), dtype=EVENT_DTYPE)
        cycle = span[recorded]
        stamps = np.floor(times[recorded] - starts[cycle]).astype(np.int64)
        events["timestamp"] = np.minimum(stamps, TDC_CODES - 1)
        events["address"] = self._addresses[pixel[recorded]]
        events["collision"] = collision
        events["pulse"] = (self.pulse + cycle) & ((1 << PULSE_BITS) - 1)
        return self._advance_pixels(cycles, count, starts, ends, events, pixel, sources, what)

    def _empty_chunk(self, start_cycles):
        chunk = super()._empty_chunk(start_cycles)
        if self._no_pixel_counts is None:
            self._no_pixel_counts = np.zeros_like(self.pixel_counts)
            self._no_pixel_counts.flags.writeable = False
        return PixelChunk(chunk.first_pulse, start_cycles, chunk.events, chunk.counts,
                          self._no_pixel_counts)

    def _advance_pixels(self, cycles, count, starts, ends, events, pixel, sources, what):
        # Photon counters: one bincount over (pixel, source, counter)
        counters = len(COUNTERS)
        key = (pixel.astype(np.int64) * self._sources + sources) * counters + what
        pixel_counts = np.bincount(key, minlength=self.pixel_counts.size).reshape(
            self.pixel_counts.shape)
        pixel_counts[:, :, _GENERATED] = pixel_counts.sum(axis=2)
        counts = pixel_counts.sum(axis=0)
        chunk = PixelChunk(self.pulse, cycles[:count].copy(), events, counts, pixel_counts)
        self.pulse += count
        self._starts.trim(self.pulse if self.external_starts else
                          min(self.pulse, self._signal.next_index))
        self._previous_end = float(starts[-1] + TDC_CODES if self._separated else ends[-1])
        self.counts += counts
        self.pixel_counts += pixel_counts
        return chunk

    def _few_pixels(self, times, sources, pixel, cycles, count, starts, span_starts, ends):
        """The rest of :meth:`step` for a few photons (in time order), in plain Python
        (:func:`~fliss.sim.scene.few.detect_pixels`: the same results)."""
        begins = starts.tolist()
        windows = (begins, None, None, True) if self._separated else \
            (begins, span_starts.tolist(), ends.tolist(), False)
        last = self._last_detections.tolist()
        recorded, what = few.detect_pixels(
            times.tolist(), pixel.tolist(), windows, self._dead, last,
            (self.scene.keep == "last", self._column, self._collision))
        self._last_detections[:] = last
        events = np.zeros(len(recorded), dtype=EVENT_DTYPE)
        if recorded:
            cycle, stamps, pixels, collisions = zip(*recorded)
            events["timestamp"] = [few.timestamp(time, begins[index])
                                   for index, time in zip(cycle, stamps)]
            events["address"] = self._addresses[list(pixels)]
            events["collision"] = collisions
            events["pulse"] = [(self.pulse + index) & ((1 << PULSE_BITS) - 1) for index in cycle]
        return self._advance_pixels(cycles, count, starts, ends, events, pixel, sources,
                                    np.array(what, dtype=np.int64))

    def _tdc(self, fires, span, pixel, times):
        """The detections the sensor's TDCs keep, of ``fires`` (indices in time order): the
        recorded indices, in event order, and their collision flags."""
        cycle = span[fires]
        last = self.scene.keep == "last"
        if not self._column:
            # One TDC per pixel: per (cycle, pixel) the last (first) detection, in address order
            order = np.lexsort((np.arange(len(fires)), pixel[fires], cycle))
            group = cycle[order] * self._pixel_count + pixel[fires][order]
            keep = np.ones(len(order), dtype=bool)
            if last:
                keep[:-1] = group[1:] != group[:-1]
            else:
                keep[1:] = group[1:] != group[:-1]
            recorded = fires[order[keep]]
            return recorded, np.zeros(len(recorded), dtype=np.uint8)
        # One TDC for the column: per cycle the last (first) detection of any pixel
        keep = np.ones(len(fires), dtype=bool)
        if last:
            keep[:-1] = cycle[1:] != cycle[:-1]
        else:
            keep[1:] = cycle[1:] != cycle[:-1]
        winners = np.flatnonzero(keep)
        # Collision: another pixel fired within the window before (after) the winner
        sequence = fires if last else fires[::-1]
        position = winners if last else len(fires) - 1 - winners
        other = _previous_other(pixel[sequence])[position]
        near = np.zeros(len(winners), dtype=bool)
        has = other >= 0
        neighbour = sequence[other[has]]
        near[has] = (span[neighbour] == cycle[winners[has]]) & \
            (np.abs(times[fires[winners[has]]] - times[neighbour]) < self._collision)
        return fires[winners], near.astype(np.uint8)
