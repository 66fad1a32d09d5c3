"""Photon generation of the scene simulator: the photons of a step, from the pulsed sources and
the background, with their draws made ahead (:mod:`~fliss.sim.scene.draws`).

:class:`PhotonGeneration` is the part of :class:`~fliss.sim.scene.photons.Simulation` that
makes a step's photons. A step of many laser cycles makes them with numpy; a step of fed starts
over a few laser cycles (closed loop, one window at a time) in plain Python, from the same
draws in the same order and with the same float64 arithmetic, so both give the same photons,
bit for bit; and a step whose pulses and spans were all drawn without photons takes a shorter
path still (:meth:`PhotonGeneration._quiet`).
"""

from bisect import bisect_right

import numpy as np

from .description import TDC_CODES, TRUNCATION_SIGMAS
from .draws import Ahead, Hits


__all__ = ["QUIET_CYCLES", "PhotonGeneration"]


#: Largest number of laser cycles a step of fed starts takes in plain Python (closed loop steps
#: one to three).
QUIET_CYCLES = 8

_LABELS = {}


def _labels(source, number):
    """``number`` times the source index ``source`` (``int8``; a read-only view of a
    constant when short: a step's few photons cost no new array)."""
    if number > 4096:
        return np.full(number, source, dtype=np.int8)
    if source not in _LABELS:
        _LABELS[source] = np.full(4096, source, dtype=np.int8)
        _LABELS[source].flags.writeable = False
    return _LABELS[source][:number]


def _clipped_normals(rng, count):
    return rng.standard_normal(count).clip(-TRUNCATION_SIGMAS, TRUNCATION_SIGMAS)


def _uniforms(rng, count):
    return rng.random(count)


class PhotonGeneration:
    """The photons of :class:`~fliss.sim.scene.photons.Simulation`'s steps (see the module)."""

    def _draws(self):
        """Per pulsed source, then for the background: its Poisson counts drawn ahead
        (:class:`~fliss.sim.scene.draws.Hits`, per pulse or per span; ``None`` when its mean is
        0), then its photons' clipped normals and uniforms (:class:`~fliss.sim.scene.draws.Ahead`;
        the background's: offsets, then pixels). Made at the first step, when a pixel array has
        set its sources' means. Each draw has a generator of its own."""
        if self._hits is None:
            array = self._pixel_count
            generators = iter(self._rng.spawn(3 * len(self._pulsed) + 3))
            self._hits = []
            means = [mean if array is None else self._per_pixel[index][0]
                     for index, (_, mean, _, _) in enumerate(self._pulsed)]
            # Background: a Poisson number per span of the longest length a span can have,
            # then thinned to each span's own length
            means.append(self._background * (TDC_CODES + self._dead) * (array or 1))
            for mean in means:
                counts, normals, uniforms = next(generators), next(generators), next(generators)
                self._hits.append((Hits(counts, mean) if mean > 0 else None,
                                   Ahead(normals, _clipped_normals), Ahead(uniforms, _uniforms)))
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
        pixel its own mean detections and arrival time (``_per_pixel``) and whose background
        falls on every pixel alike."""
        array = self._pixel_count
        draws = self._draws()
        times, sources, owners = [self._carry_times], [self._carry_sources], [self._carry_pixels]
        for index, (pulses, _, sigma, wander) in enumerate(self._pulsed):
            centres = pulses.until(self._limit(boundary, index))
            hits, normals, uniforms = draws[index]
            if hits is None or len(centres) == 0:
                continue
            # Each pulse's Poisson number of photons (for a pixel array, of the array's
            # photons, shared out by the pixels' means: the same law as each pixel's own)
            pulse, number = hits.take(len(centres))
            if not len(pulse):
                continue
            centres = centres[pulse]
            if wander > 0:
                centres = centres + wander * normals.array(len(centres))
            arrivals = np.repeat(centres, number)
            number = len(arrivals)
            if array is not None:
                _, extra, _, shares = self._per_pixel[index]
                pixel = np.searchsorted(shares, uniforms.array(number), side="right")
                pixel = np.minimum(pixel, array - 1).astype(np.int16)
                owners.append(pixel)
                arrivals = arrivals + extra[pixel]
            times.append(arrivals + sigma * normals.array(number))
            sources.append(_labels(index if index == 0 else index + 1, number))
        hits, _, uniforms = draws[-1]
        span, number = hits.take(count) if hits is not None else ((), ())
        if len(span):
            # A Poisson process on each span: drawn on spans all as long as the longest a span
            # can be (its window and the dead time before), thinned to each span's length.
            span = np.repeat(span, number)
            number = len(span)
            offset = (TDC_CODES + self._dead) * uniforms.array(number)
            if array is not None and self._background_shares is None:
                pixel = (uniforms.array(number) * array).astype(np.int16)
            elif array is not None:
                pixel = np.minimum(np.searchsorted(self._background_shares,
                                                   uniforms.array(number), side="right"),
                                   array - 1).astype(np.int16)
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
        if len(times) == 1:
            return times[0], sources[0], owners[0]
        return (np.concatenate(times), np.concatenate(sources),
                None if array is None else np.concatenate(owners))

    def _plain_photons(self, boundary, windows, handed):
        """:meth:`_photons` in plain Python for a step of a few laser cycles (``windows``:
        ``(starts, span_starts, ends)``, lists), the pulses each source hands out counted
        (``handed``); the same photons, as arrays."""
        array = self._pixel_count
        draws = self._draws()
        times, sources = self._carry_times.tolist(), self._carry_sources.tolist()
        owners = None if array is None else self._carry_pixels.tolist()
        for index, (pulses, _, sigma, wander) in enumerate(self._pulsed):
            centres = pulses.centres(handed[index])
            hits, normals, uniforms = draws[index]
            if hits is None or not centres:
                continue
            pulse, number = hits.take(len(centres))
            if not len(pulse):
                continue
            centres = [centres[at] for at in pulse.tolist()]
            if wander > 0:
                centres = [centre + wander * normal
                           for centre, normal in zip(centres, normals.list(len(centres)))]
            arrivals = [centre for centre, repeat in zip(centres, number.tolist())
                        for _ in range(repeat)]
            number = len(arrivals)
            if array is not None:
                shares, extra = self._plain_shares[index]
                pixel = [min(bisect_right(shares, uniform), array - 1)
                         for uniform in uniforms.list(number)]
                owners += pixel
                arrivals = [arrival + extra[at] for arrival, at in zip(arrivals, pixel)]
            times += [arrival + sigma * normal
                      for arrival, normal in zip(arrivals, normals.list(number))]
            sources += [index if index == 0 else index + 1] * number
        hits, _, uniforms = draws[-1]
        span, number = hits.take(len(windows[0])) if hits is not None else ((), ())
        if len(span):
            span = [at for at, repeat in zip(span.tolist(), number.tolist())
                    for _ in range(repeat)]
            longest = TDC_CODES + self._dead
            offsets = [longest * uniform for uniform in uniforms.list(len(span))]
            pixel = None
            if array is not None and self._background_shares is None:
                pixel = [int(uniform * array) for uniform in uniforms.list(len(span))]
            elif array is not None:
                shares = self._plain_background_shares
                pixel = [min(bisect_right(shares, uniform), array - 1)
                         for uniform in uniforms.list(len(span))]
            starts, span_starts, ends = windows
            if self._separated:
                arrivals = [starts[at] + (offset - self._dead) for at, offset in zip(span, offsets)]
            else:
                inside = [offset < ends[at] - span_starts[at] for at, offset in zip(span, offsets)]
                arrivals = [span_starts[at] + offset
                            for at, offset, keep in zip(span, offsets, inside) if keep]
                if pixel is not None:
                    pixel = [at for at, keep in zip(pixel, inside) if keep]
            times += arrivals
            sources += [1] * len(arrivals)
            if pixel is not None:
                owners += pixel
        return (np.array(times, dtype=np.float64), np.array(sources, dtype=np.int8),
                None if array is None else np.array(owners, dtype=np.int16))

    def _prepare(self, max_cycles, until_cycle):
        """The laser cycles of the next step and their photons: a chunk when the step is empty
        (no cycle, or, fed starts over a few cycles, no photon), else ``(cycles, count, (starts,
        span_starts, ends, boundary), (times, sources, pixels))`` (arrays)."""
        plain = self._plain_cycles(max_cycles, until_cycle) if self.external_starts else None
        if plain is None:
            cycles, count = self._cycles(max_cycles, until_cycle)
            if count == 0:
                return self._empty_chunk(cycles[:0].copy())
            windows = self._windows(cycles, count)
            return cycles, count, windows, self._photons(*windows[3:], count, *windows[:3])
        cycles, count = plain
        # The windows, as _windows makes them
        lsb, dead = self._lsb, self._dead
        edges = [cycle * lsb for cycle in cycles[:count + 1]]
        starts = edges[:-1]
        if self._separated:
            span_starts = ends = None
            boundary = edges[-1] - dead
            previous_end = edges[-2] + TDC_CODES
        else:
            ends = [min(start + TDC_CODES, edge) for start, edge in zip(starts, edges[1:])]
            span_starts = [max(start - dead, end)
                           for start, end in zip(starts, [self._previous_end] + ends[:-1])]
            previous_end = ends[-1]
            boundary = max(edges[-1] - dead, previous_end)
        handed = self._quiet(boundary, count)
        if handed is None:
            chunk = self._empty_chunk(np.array(cycles[:count], dtype=np.int64))
            self.pulse += count
            self._starts.trim(self.pulse)
            self._previous_end = previous_end
            return chunk
        photons = self._plain_photons(boundary, (starts, span_starts, ends), handed)
        windows = (np.array(starts), None if span_starts is None else np.array(span_starts),
                   None if ends is None else np.array(ends), boundary)
        return np.array(cycles, dtype=np.int64), count, windows, photons

    def _plain_cycles(self, max_cycles, until_cycle):
        """``(cycles, count)`` of the next step, as :meth:`_cycles`, as a list, when it is of a
        few laser cycles (at most ``quiet_cycles``); else ``None``."""
        max_cycles = self.chunk_cycles if max_cycles is None else int(max_cycles)
        most = self.quiet_cycles
        cycles = self._starts.values(self.pulse, self.pulse + min(max_cycles, most) + 1)
        count = min(max_cycles, len(cycles) - 1)
        if until_cycle is not None:
            count = min(count, sum(cycle < until_cycle for cycle in cycles))
        if count <= 0 or (count == most and max_cycles > most):
            return None
        return cycles, count

    def _quiet(self, boundary, count):
        """A step of ``count`` laser cycles up to ``boundary``: the pulses each source hands
        out; or, when nothing is carried over and every pulse and span was drawn without a
        photon, ``None``, its pulses and spans handed out (:meth:`_prepare` then moves on)."""
        if self._quiet_sources is None:
            draws = self._draws()
            self._quiet_sources = [(pulses, draws[index][0], *self._reach(index))
                                   for index, (pulses, *_) in enumerate(self._pulsed)]
            self._plain_shares = None if self._pixel_count is None else \
                [(shares.tolist(), extra.tolist()) for _, extra, _, shares in self._per_pixel]
            self._plain_background_shares = None if self._background_shares is None else \
                self._background_shares.tolist()
        handed = [pulses.count_until(boundary + spread + 1.0 - lowest)
                  for pulses, _, spread, lowest in self._quiet_sources]
        if len(self._carry_times):
            return handed
        for (_, hits, *_), number in zip(self._quiet_sources, handed):
            if number and hits is not None and not hits.quiet(number):
                return handed
        background = self._hits[-1][0]
        if background is not None and not background.quiet(count):
            return handed
        for (pulses, hits, *_), number in zip(self._quiet_sources, handed):
            pulses.skip(number)
            if hits is not None:
                hits.skip(number)
        if background is not None:
            background.skip(count)
        return None

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
