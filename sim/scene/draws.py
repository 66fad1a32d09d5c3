"""Poisson counts drawn ahead in blocks, for the scene simulator's sources.

A pulsed source gives each of its pulses a Poisson number of detections, the background each
span a Poisson number of photons; :class:`Hits` draws those counts for thousands of pulses
(spans) at a time and keeps the ones that are not zero, so a step of the simulation sees at
once whether its pulses have any photon (in closed loop, most steps have none) and takes the
counts of many pulses with one call. Each source has a generator of its own (spawned from the
simulation's), so its counts do not depend on how the run is cut into steps.
"""

import math

import numpy as np


__all__ = ["SPARSE_MEAN", "Hits", "Ahead"]


#: Largest mean whose Poisson counts :class:`Hits` draws as the gaps between non-zero counts.
SPARSE_MEAN = 1.0


class Hits:
    """Independent Poisson counts of mean ``mean``, one per pulse (span) in order, drawn from
    ``rng`` and kept as the indices and values of the counts that are not zero.

    A mean under :data:`SPARSE_MEAN` draws those directly, ``block`` at a time: the gaps
    between them (geometric, of the probability ``1 - exp(-mean)`` that a count is not zero)
    and their values (Poisson conditioned on being at least one, by inversion of its
    cumulative distribution, cut where the rest is under ``1e-17``): the same law as a Poisson
    draw per pulse, at a cost per photon rather than per pulse. A larger mean draws the counts
    of ``block`` pulses at a time."""

    def __init__(self, rng, mean, block=1 << 12):
        self._rng, self._mean = rng, float(mean)
        self._sparse = self._mean < SPARSE_MEAN
        self._block = block if self._sparse else block << 4
        if self._sparse:
            self._hit = -math.expm1(-self._mean)        # a count is not zero
            terms, term, k = [], math.exp(-self._mean), 0
            while k < 2 or term > 1e-17 * self._hit:    # P(count = k), k from 1 on
                k += 1
                term *= self._mean / k
                terms.append(term)
            self._cumulative = np.cumsum(terms)
        self._drawn = 0                 # counts drawn so far
        self._taken = 0                 # counts taken so far
        self._where = np.zeros(0, dtype=np.int64)     # indices of the non-zero counts drawn
        self._counts = np.zeros(0, dtype=np.int64)    # and those counts
        self._head = 0                  # first of them not taken
        #: Index of the next non-zero count.
        self.next_hit = 0
        self._refill()

    def _refill(self):
        while self._head == len(self._where):
            if self._sparse:
                where = self._drawn - 1 + np.cumsum(self._rng.geometric(self._hit, self._block))
                level = self._rng.random(self._block) * self._cumulative[-1]
                counts = np.minimum(np.searchsorted(self._cumulative, level, side="right") + 1,
                                    len(self._cumulative))
                self._drawn = int(where[-1]) + 1
            else:
                counts = self._rng.poisson(self._mean, self._block)
                where = np.flatnonzero(counts)
                counts = counts[where]
                where = where + self._drawn
                self._drawn += self._block
            self._where, self._counts, self._head = where, counts, 0
        self.next_hit = int(self._where[self._head])

    def quiet(self, count):
        """Whether the next ``count`` counts are all zero."""
        return self._taken + count <= self.next_hit

    def skip(self, count):
        """Take the next ``count`` counts, all zero (see :meth:`quiet`)."""
        self._taken += count

    def take(self, count):
        """The next ``count`` counts: ``(offsets, counts)`` of the non-zero ones, offsets from
        the first (``int64`` arrays)."""
        end = self._taken + count
        offsets, counts = [], []
        while self.next_hit < end:
            stop = self._head + int(np.searchsorted(self._where[self._head:], end))
            offsets.append(self._where[self._head:stop] - self._taken)
            counts.append(self._counts[self._head:stop])
            self._head = stop
            if self._head == len(self._where):
                self._refill()
            else:
                self.next_hit = int(self._where[self._head])
        self._taken = end
        if len(offsets) == 1:
            return offsets[0], counts[0]
        if not offsets:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        return np.concatenate(offsets), np.concatenate(counts)


class Ahead:
    """Independent draws ``draw(rng, count)`` (an array), made ``block`` at a time and taken in
    order, as an array or as a list of Python floats (the same values either way)."""

    def __init__(self, rng, draw, block=4096):
        self._rng, self._draw, self._block = rng, draw, block
        self._array = np.zeros(0)
        self._list = []
        self._head = 0

    def _fill(self, count):
        rest = self._array[self._head:]
        blocks = -(-(count - len(rest)) // self._block)
        self._array = np.concatenate((rest, self._draw(self._rng, blocks * self._block)))
        self._list = None               # made when a list is asked for
        self._head = 0

    def array(self, count):
        """The next ``count`` draws, an array."""
        if self._head + count > len(self._array):
            self._fill(count)
        self._head += count
        return self._array[self._head - count:self._head]

    def list(self, count):
        """The next ``count`` draws, a list."""
        if self._head + count > len(self._array):
            self._fill(count)
        if self._list is None:
            self._list = self._array.tolist()
        self._head += count
        return self._list[self._head - count:self._head]
