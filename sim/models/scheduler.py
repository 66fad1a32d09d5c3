"""Bit-exact model of :class:`fliss.hdl.delay.scheduler.PulseScheduler` and
:class:`fliss.hdl.delay.laser.LaserTrigger`, and the effective PRF (equation 4 of the paper).

Cycle numbers count from the first take cycle ``b[0]`` (the cycle after ``enable`` rises) unless
a ``start`` is given. Pulse ``k`` is fired (``fire`` high) in cycle ``b[k] + 1 + R[k]``; the laser
rises and the TDC starts ``LATENCY`` cycles later.
"""

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ...hdl.delay.laser import LATENCY
from ...hdl.delay.modes import MODES
from ...hdl.delay.settings import KEYED_START_CYCLES, PERIOD_WIDTH, PULSE_WIDTH_WIDTH
from . import delay as _delay
from . import trivium as _trivium


__all__ = ["prf_rows", "MEASURE_LIMIT", "LATENCY", "Settings", "check_schedule", "frame_lengths", "fire_cycles",
           "effective_prf", "measured_prf", "start_cycle", "simulate"]


def check_schedule(period, pulse_width, *, grid=False, max_delay=0):
    """Validate scheduler settings in cycles; raise :exc:`ValueError` with the reason.

    The laser must go low for at least one cycle between pulses: ``pulse_width < period``, and in
    ``grid`` mode ``max_delay + pulse_width < period`` as well.
    """
    if not isinstance(period, (int, np.integer)) or not 2 <= period < (1 << PERIOD_WIDTH):
        raise ValueError(f"Period must be from 2 to {(1 << PERIOD_WIDTH) - 1} clock cycles, "
                         f"not {period!r}")
    if not isinstance(pulse_width, (int, np.integer)) or \
            not 1 <= pulse_width < (1 << PULSE_WIDTH_WIDTH):
        raise ValueError(f"Pulse width must be from 1 to {(1 << PULSE_WIDTH_WIDTH) - 1} clock "
                         f"cycles, not {pulse_width!r}")
    if pulse_width >= period:
        raise ValueError(f"Pulse width ({pulse_width} cycles) must be shorter than the period "
                         f"({period} cycles)")
    if grid and max_delay + pulse_width >= period:
        raise ValueError(f"Grid mode needs the largest delay plus the pulse width "
                         f"({max_delay} + {pulse_width} cycles) to be shorter than the period "
                         f"({period} cycles); use interval mode, a longer period or a "
                         f"shorter delay")


def frame_lengths(delays, period, *, grid=False):
    """Length of each frame in cycles: ``T + R`` (interval) or ``T`` (grid)."""
    delays = np.asarray(delays, dtype=np.int64)
    if grid:
        return np.full(delays.shape, period, dtype=np.int64)
    return period + delays


def fire_cycles(delays, period, *, grid=False, start=0):
    """Cycle in which each pulse is fired, with ``b[0] = start``."""
    delays = np.asarray(delays, dtype=np.int64)
    lengths = frame_lengths(delays, period, grid=grid)
    takes = start + np.concatenate(([0], np.cumsum(lengths[:-1])))
    return takes + 1 + delays


def effective_prf(clock_hz, period, mean_delay, *, grid=False):
    """Effective PRF in Hz, equation 4: ``f_clk / (T + E(R))``; ``f_clk / T`` in grid mode."""
    if grid:
        return Fraction(clock_hz) / period
    return Fraction(clock_hz) / (period + Fraction(mean_delay))


def measured_prf(clock_hz, fires):
    """PRF in Hz measured from fire cycles: pulses per cycle between the first and last pulse."""
    fires = np.asarray(fires, dtype=np.int64)
    if len(fires) < 2:
        raise ValueError("Measuring a PRF needs at least two pulses")
    return Fraction(clock_hz) * (len(fires) - 1) / int(fires[-1] - fires[0])


@dataclass(frozen=True)
class Settings:
    """Run-time settings of the delay core, in clock cycles."""
    mode: object = _delay.DelayMode.OFF
    length: int = 8
    mask_width: int = 6
    seed: int = 1
    period: int = 80
    grid: bool = False
    pulse_width: int = 1
    #: Key and IV of the ``keyed`` source (80-bit integers), as written.
    key: int = 0
    iv: int = 0

    def check(self):
        """Raise :exc:`ValueError` unless the settings are valid together."""
        mode = _delay.check_settings(self.mode, length=self.length, mask_width=self.mask_width,
                                     seed=self.seed, key=self.key, iv=self.iv)
        check_schedule(self.period, self.pulse_width, grid=self.grid,
                       max_delay=_delay.max_delay(mode, length=self.length,
                                                  mask_width=self.mask_width))
        return self

    @property
    def keyed(self):
        return MODES[_delay.parse_mode(self.mode)].keyed

    def delays(self, count):
        return _delay.delays(self.mode, count, length=self.length, mask_width=self.mask_width,
                             seed=self.seed, key=self.key, iv=self.iv)


class _Keystream:
    """The ``keyed`` source's keystream as the gateware keeps it across loads: delays of any
    width from one Trivium stream, restarted by :class:`~fliss.sim.models.delay.KeyedRestarts`."""

    def __init__(self, restarts):
        self.restarts = restarts
        self._stream = None
        self._first_take = None     # cycle of the first take since the initialisation
        #: First cycle in which the scheduler may run with the keystream (not busy).
        self.ready_at = None

    def load(self, settings, cycle):
        """A load with ``settings`` (in any mode: a load in another mode may leave the source
        spent) in ``cycle``; True if it initialises."""
        restarts = self.restarts
        if (settings.key, settings.iv) != (restarts.key, restarts.written_iv):
            restarts.write(key=settings.key, iv=settings.iv)
        # (a take in the load's cycle is not yet a use: the gateware's flag is a register)
        just_used = self._first_take == cycle
        if just_used:
            restarts._used = False
        initialises = restarts.load(keyed=settings.keyed)
        if not settings.keyed:
            restarts._used = restarts._used or just_used
            return False
        if initialises or self._stream is None:
            # (a stream not initialised here was, before the run, with the IV in use)
            self._stream = _trivium.Trivium(restarts.key, restarts.iv)
            self._first_take = None
        if initialises:
            self.ready_at = cycle + KEYED_START_CYCLES
        elif restarts.spent:
            self.ready_at = math.inf    # (no IV left under the key: never ready)
        elif just_used:
            restarts._used = True
        return initialises

    def take(self, width, cycle):
        if not self.restarts._used:
            self._first_take = cycle
        self.restarts.take()
        bits = self._stream.bits(width)
        return int((bits.astype(np.int64) << np.arange(width)).sum())

    def busy(self, cycle):
        return self.ready_at is not None and cycle < self.ready_at


def start_cycle(enable, pulses):
    """The cycle a run whose ``enable`` rises in cycle ``enable`` starts in (the ``enable`` to
    give :func:`simulate` for it), after the ``pulses`` of the runs before it: the delay core
    holds a start back until the laser is off, so that a stop and a quick restart cannot merge
    the last pulse of one run with the first of the next."""
    laser_off = max((fire + LATENCY + max(width, 1) for fire, _, width, _ in pulses),
                    default=enable)
    return max(enable, laser_off)


def simulate(settings, until, *, updates=(), enable=0, disable=None, restarts=None):
    """Pulses of the delay core, cycle by cycle, with reconfiguration.

    ``keyed`` settings (``restarts``, a :class:`~fliss.sim.models.delay.KeyedRestarts`: the state of
    the source before the run; its key and IV are written when the settings' differ): a run's
    keystream is that of the IV in use. First settings that are ``keyed`` must be presented from
    cycle ``enable`` on; if they initialise the source, the run starts
    :data:`~fliss.hdl.delay.settings.KEYED_START_CYCLES` later. An update presenting ``keyed``
    settings while the source is not ready (it initialises now or did recently) stops the run
    in the next cycle (no pulse fires after the update's cycle); it starts again once the
    source is ready, or a cycle after an update presenting another mode (and once the laser is
    off), its pulses counted from 0. A source spent (every IV under its key used,
    :class:`~fliss.sim.models.delay.KeyedRestarts`) is never ready: no pulse fires in ``keyed``
    mode until settings with a new key or IV (the register file lets only a new key through
    then), or of another mode, are presented.

    Parameters
    ----------
    settings : Settings
        Settings present while ``enable`` rises.
    until : int
        Last cycle to simulate.
    updates : list of (int, Settings)
        ``update`` strobes while running: cycle and the settings presented in that cycle.
    enable : int
        Cycle in which ``enable`` rises; the first take cycle is the next one.
    disable : int or None
        Cycle in which ``enable`` falls; no pulse fires from then on.

    Returns
    -------
    list of (fire_cycle, delay, pulse_width, pulse_index)
    """
    updates = sorted(updates, key=lambda update: update[0])
    keystream = _Keystream(_delay.KeyedRestarts() if restarts is None else restarts)
    pulses = []
    first = 0               # index in `pulses` of the run's first pulse
    current = settings
    sequence = iter(())
    restart = True
    next_update = 0

    def stopped(start):
        # While the keystream is not ready, the scheduler stays stopped, sampling the settings
        # presented: until `start` (moved by settings that initialise it again), or until
        # settings of another mode. The start cycle, before the laser is checked.
        nonlocal current, next_update
        while next_update < len(updates) and updates[next_update][0] < start:
            cycle, current = updates[next_update]
            next_update += 1
            keystream.load(current, cycle)
            if not current.keyed:
                return cycle + 1        # (the source's mode changes a cycle after the load)
            start = keystream.ready_at
        return start

    if current.keyed:
        keystream.load(current, enable)
        if keystream.busy(enable):
            enable = stopped(keystream.ready_at)
    take = enable + 1
    stop = until + 1 if disable is None else min(until + 1, disable)
    while take < stop:
        # Settings presented on update strictly before this take apply to this frame.
        while next_update < len(updates) and updates[next_update][0] < take:
            cycle, current = updates[next_update]
            restart = True
            next_update += 1
            keystream.load(current, cycle)
            if not current.keyed:
                continue
            if not keystream.busy(cycle):
                continue
            # The run stops, and starts again once the keystream is ready, or on settings of
            # another mode (the scheduler samples them while stopped).
            pulses = [pulse for pulse in pulses if pulse[0] <= cycle]
            first = len(pulses)
            take = start_cycle(stopped(keystream.ready_at), pulses) + 1
        if take >= stop:
            break
        if current.keyed:
            delay = keystream.take(current.mask_width, take)
        else:
            if restart:
                sequence = iter(current.delays(_SEQUENCE_CHUNK))
            try:
                delay = int(next(sequence))
            except StopIteration:  # pragma: no cover - chunk sized to outlast any simulation
                raise RuntimeError("delay sequence exhausted") from None
        restart = False
        fire = take + 1 + delay
        if fire < stop:
            pulses.append((fire, delay, current.pulse_width, len(pulses) - first))
        take += current.period + (0 if current.grid else delay)
    return pulses


#: Delays generated per (re)start: more pulses than any run `simulate` is asked for.
_SEQUENCE_CHUNK = 1 << 16


#: Whole sequences up to this many pulses are also measured by :func:`prf_rows`, by generating
#: them.
MEASURE_LIMIT = 1 << 20


def prf_rows(clock_hz, period, sizes, *, grid=False):
    """Rows of the PRF table: (source, setting, max delay, mean delay, PRF closed form,
    PRF measured or None), for every mode of :data:`~fliss.hdl.delay.modes.MODES` sized by a
    setting in ``sizes`` (setting name -> values: ``{"length": [3, 4]}``), in table order."""
    rows = []
    sources = [(row.name, {row.size: value}) for row in MODES.values()
               for value in sizes.get(row.size, ())]
    for mode, setting in sources:
        max_delay = _delay.max_delay(mode, **setting)
        mean_delay = _delay.mean_delay(mode, **setting)
        if grid:
            check_schedule(period, 1, grid=True, max_delay=max_delay)
        closed = effective_prf(clock_hz, period, mean_delay, grid=grid)
        pulses = _delay.sequence_period(mode, **setting)
        measured = None
        if pulses is not None and pulses <= MEASURE_LIMIT:
            delays = _delay.delays(mode, pulses + 1, **setting)
            measured = measured_prf(
                clock_hz, fire_cycles(delays, period, grid=grid))
        rows.append((mode, setting, max_delay, mean_delay, closed, measured))
    return rows
