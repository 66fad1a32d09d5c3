"""Laser rising edges and pulse arrival times for the scene simulator, made block by block.

:class:`EdgeSchedule` gives the rising edges of a delay core from the reference scheduler,
:class:`EdgeBuffer` holds an increasing sequence of edges (made by a schedule or fed from outside),
and :class:`PulseTrain` hands out the arrival times of one pulsed source in increasing order.
"""

import math

import numpy as np

from ..models import scheduler as _scheduler
from ..models.delay import block_stream


__all__ = ["EdgeSchedule", "EdgeBuffer", "PulseTrain", "fed_edges"]


class EdgeSchedule:
    """Laser rising edges (TDC starts) of a delay core, in clock cycles, block by block.

    With ``fine_step`` > 1 the delays count in steps of ``1 / fine_step`` cycle (a model
    option) and the edges are ``float64``."""

    def __init__(self, settings, block, fine_step=1):
        self._settings = settings
        self._fine = fine_step
        self._delays = block_stream(settings.mode, block, length=settings.length,
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
        if self._fine != 1:
            delays = delays / self._fine
            if grid:
                fires = (self._take + period * np.arange(len(delays))) + 1 + delays
                self._take += period * len(delays)
                return fires + _scheduler.LATENCY
        if grid:
            fires = _scheduler.fire_cycles(delays, period, grid=True, start=self._take)
            self._take += period * len(delays)
            return fires + _scheduler.LATENCY
        # Interval mode, as fire_cycles: pulse k fires 1 + R[k] cycles after its take cycle
        # start + sum(T + R[i], i < k), that is at start + cumsum(T + R)[k] - T + 1.
        ends = np.cumsum(delays + period)
        edges = ends + (self._take - period + 1 + _scheduler.LATENCY)
        self._take += ends[-1] if len(ends) else 0
        return edges

    def __call__(self):
        if self._pattern is not None:
            edges = self._pattern + self._take
            self._take += self._length
            return edges
        return self._edges(self._delays.block())


def fed_edges(values, last, what, caller):
    """``values``, edges fed from outside (one integer, or a 1-D array of integers) after
    ``last`` (``None``: none before), checked: an ``int``, or an ``int64`` array; the
    ``ValueError`` names them as ``what`` and the method as ``caller``."""
    if isinstance(values, (int, np.integer)) and not isinstance(values, bool):
        values = int(values)
        if last is not None and values <= last:
            raise ValueError(f"{what} must increase strictly, also across calls to {caller}()")
        return values
    values = np.asarray(values)
    if values.ndim != 1 or (len(values) and values.dtype.kind not in "iu"):
        raise ValueError(f"{what} must be a 1-D array of whole clock cycles")
    values = values.astype(np.int64)
    if len(values) and ((last is not None and values[0] <= last)
                        or np.any(values[1:] <= values[:-1])):
        raise ValueError(f"{what} must increase strictly, also across calls to {caller}()")
    return values


class EdgeBuffer:
    """An increasing sequence read by global index, made block by block by ``blocks()`` or, when
    ``blocks`` is ``None``, fed from outside (then ``get`` returns what is known; fed values are
    kept as a list of Python integers, cheap to feed and read one at a time)."""

    def __init__(self, blocks):
        self._blocks = blocks
        self._data = np.zeros(0, dtype=np.int64) if blocks is not None else []
        self._base = 0
        #: The last value fed (``None`` before any).
        self.last = None

    @property
    def end(self):
        """Index after the last value known."""
        return self._base + len(self._data)

    def feed(self, values):
        """Feed values (as :func:`fed_edges` returns them: an ``int`` or an ``int64`` array)."""
        if isinstance(values, int):
            self._data.append(values)
            self.last = values
        elif len(values):
            self._data.extend(values.tolist())
            self.last = self._data[-1]

    def get(self, lo, hi):
        """Values ``lo`` to ``hi`` (those known), an ``int64`` array (with ``blocks``, of
        whatever type the blocks are)."""
        if self._blocks is None:
            return np.array(self._data[lo - self._base:hi - self._base], dtype=np.int64)
        while self._base + len(self._data) < hi:
            self._data = np.concatenate((self._data[lo - self._base:], self._blocks()))
            self._base = lo
        return self._data[lo - self._base:hi - self._base]

    def values(self, lo, hi):
        """:meth:`get` as a list of Python numbers."""
        if self._blocks is None:
            return self._data[lo - self._base:hi - self._base]
        return self.get(lo, hi).tolist()

    def trim(self, lo):
        if lo > self._base:
            if self._blocks is None:
                del self._data[:lo - self._base]
            else:
                self._data = self._data[lo - self._base:]
            self._base = lo


_NO_PULSES = np.zeros(0)
_NO_PULSES.flags.writeable = False


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
            if not len(cycles):
                return _NO_PULSES
            centres = cycles * self._scale + self._shift
            found = int(centres.searchsorted(limit, side="left"))
            if found < len(centres) or len(centres) < count:
                break                       # past the limit, or no more pulses known yet
            count *= 2
        self._next += found
        if self._trim:
            self._buffer.trim(self._next)
        return centres[:found]

    def count_until(self, limit):
        """How many pulses :meth:`until` would hand out (it does not hand them out)."""
        if self._buffer is None:
            return max(self._next, math.ceil((limit - self._shift) / self._step)) - self._next
        count = 8
        while True:
            found = 0
            cycles = self._buffer.values(self._next, self._next + count)
            for cycle in cycles:
                if cycle * self._scale + self._shift >= limit:
                    return found
                found += 1
            if len(cycles) < count:
                return found
            count *= 4

    def centres(self, count):
        """The centres of the next ``count`` pulses (as :meth:`count_until` counted them), a
        list, handed out: the values :meth:`until` gives."""
        if self._buffer is None:
            centres = [self._shift + pulse * self._step
                       for pulse in range(self._next, self._next + count)]
        else:
            centres = [cycle * self._scale + self._shift
                       for cycle in self._buffer.values(self._next, self._next + count)]
        self.skip(count)
        return centres

    def skip(self, count):
        """Hand out the next ``count`` pulses unseen (as :meth:`count_until` counted them)."""
        self._next += count
        if self._trim and self._buffer is not None:
            self._buffer.trim(self._next)

    @property
    def next_index(self):
        return self._next
