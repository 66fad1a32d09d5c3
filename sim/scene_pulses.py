"""Laser rising edges and pulse arrival times for the scene simulator, made block by block.

:class:`EdgeSchedule` gives the rising edges of a delay core from the reference scheduler,
:class:`EdgeBuffer` holds an increasing sequence of edges (made by a schedule or fed from outside),
and :class:`PulseTrain` hands out the arrival times of one pulsed source in increasing order.
"""

import math

import numpy as np

from . import scheduler as _scheduler
from .delay import DelayStream


__all__ = ["EdgeSchedule", "EdgeBuffer", "PulseTrain"]


class EdgeSchedule:
    """Laser rising edges (TDC starts) of a delay core, in clock cycles, block by block."""

    def __init__(self, settings, block):
        self._settings = settings
        self._delays = DelayStream(settings.mode, length=settings.length,
                                   mask_width=settings.mask_width, seed=settings.seed,
                                   key=settings.key, iv=settings.iv)
        self._take = 0
        self._block = block
        self._pattern = None
        table = self._delays.table
        if table is not None:
            # A short sequence: the edges of whole sequence periods, computed once and shifted.
            delays = np.tile(table, max(1, -(-block // len(table))))
            self._pattern = self._edges(delays)
            self._length = self._take
            self._take = 0

    def _edges(self, delays):
        period, grid = self._settings.period, self._settings.grid
        if grid:
            fires = _scheduler.fire_cycles(delays, period, grid=True, start=self._take)
            self._take += period * len(delays)
            return fires + _scheduler.LATENCY
        # Interval mode, as fire_cycles: pulse k fires 1 + R[k] cycles after its take cycle
        # start + sum(T + R[i], i < k), that is at start + cumsum(T + R)[k] - T + 1.
        ends = np.cumsum(delays + period)
        edges = ends + (self._take - period + 1 + _scheduler.LATENCY)
        self._take += int(ends[-1]) if len(ends) else 0
        return edges

    def __call__(self):
        if self._pattern is not None:
            edges = self._pattern + self._take
            self._take += self._length
            return edges
        return self._edges(self._delays.block())


class EdgeBuffer:
    """An increasing sequence read by global index, made block by block by ``blocks()`` or, when
    ``blocks`` is ``None``, fed from outside (then ``get`` returns what is known)."""

    def __init__(self, blocks):
        self._blocks = blocks
        self._data = np.zeros(0, dtype=np.int64)
        self._base = 0

    @property
    def end(self):
        """Index after the last value known."""
        return self._base + len(self._data)

    def feed(self, values):
        self._data = np.concatenate((self._data, values))

    def get(self, lo, hi):
        while self._base + len(self._data) < hi and self._blocks is not None:
            self._data = np.concatenate((self._data[lo - self._base:], self._blocks()))
            self._base = lo
        return self._data[lo - self._base:hi - self._base]

    def trim(self, lo):
        if lo > self._base:
            self._data = self._data[lo - self._base:]
            self._base = lo


class PulseTrain:
    """Arrival times (pulse centres, LSBs) of one pulsed source, handed out in increasing order."""

    def __init__(self, buffer=None, *, scale=1.0, shift=0.0, step=None, guess=4096, trim=True):
        self._buffer = buffer
        self._trim = trim
        self._scale, self._shift, self._step = scale, shift, step
        self._next = 0
        self._guess = guess

    def until(self, limit):
        """Centres of the pulses not handed out yet that arrive before ``limit``."""
        if self._buffer is None:
            # Arithmetic train: centre of pulse j is shift + j * step.
            end = max(self._next, math.ceil((limit - self._shift) / self._step))
            centres = self._shift + np.arange(self._next, end, dtype=np.float64) * self._step
            self._next = end
            return centres
        count = self._guess
        while True:
            cycles = self._buffer.get(self._next, self._next + count)
            centres = cycles * self._scale + self._shift
            found = int(np.searchsorted(centres, limit, side="left"))
            if found < len(centres) or len(centres) < count:
                break                       # past the limit, or no more pulses known yet
            count *= 2
        self._next += found
        if self._trim:
            self._buffer.trim(self._next)
        return centres[:found]

    @property
    def next_index(self):
        return self._next
