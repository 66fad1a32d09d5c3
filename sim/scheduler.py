"""Bit-exact model of :class:`fliss.hdl.scheduler.PulseScheduler` and
:class:`fliss.hdl.laser.LaserTrigger`, and the effective PRF (equation 4 of the paper).

Cycle numbers count from the first take cycle ``b[0]`` (the cycle after ``enable`` rises) unless
a ``start`` is given. Pulse ``k`` is fired (``fire`` high) in cycle ``b[k] + 1 + R[k]``; the laser
rises and the TDC starts ``LATENCY`` cycles later.
"""

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ..hdl.laser import LATENCY
from ..hdl.settings import PERIOD_WIDTH, PULSE_WIDTH_WIDTH
from . import delay as _delay


__all__ = ["LATENCY", "Settings", "check_schedule", "frame_lengths", "fire_cycles",
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

    def check(self):
        """Raise :exc:`ValueError` unless the settings are valid together."""
        mode = _delay.check_settings(self.mode, length=self.length, mask_width=self.mask_width,
                                     seed=self.seed)
        check_schedule(self.period, self.pulse_width, grid=self.grid,
                       max_delay=_delay.max_delay(mode, length=self.length,
                                                  mask_width=self.mask_width))
        return self

    def delays(self, count):
        return _delay.delays(self.mode, count, length=self.length, mask_width=self.mask_width,
                             seed=self.seed)


def start_cycle(enable, pulses):
    """The cycle a run whose ``enable`` rises in cycle ``enable`` starts in (the ``enable`` to
    give :func:`simulate` for it), after the ``pulses`` of the runs before it: the delay core
    holds a start back until the laser is off, so that a stop and a quick restart cannot merge
    the last pulse of one run with the first of the next."""
    laser_off = max((fire + LATENCY + max(width, 1) for fire, _, width, _ in pulses),
                    default=enable)
    return max(enable, laser_off)


def simulate(settings, until, *, updates=(), enable=0, disable=None):
    """Pulses of the delay core, cycle by cycle, with reconfiguration.

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
    pulses = []
    take = enable + 1
    current = settings
    sequence = iter(())
    restart = True
    next_update = 0
    stop = until + 1 if disable is None else min(until + 1, disable)
    while take < stop:
        # Settings presented on update strictly before this take apply to this frame.
        while next_update < len(updates) and updates[next_update][0] < take:
            current = updates[next_update][1]
            restart = True
            next_update += 1
        if restart:
            sequence = iter(current.delays(_SEQUENCE_CHUNK))
            restart = False
        try:
            delay = int(next(sequence))
        except StopIteration:  # pragma: no cover - chunk sized to outlast any simulation
            raise RuntimeError("delay sequence exhausted") from None
        fire = take + 1 + delay
        if fire < stop:
            pulses.append((fire, delay, current.pulse_width, len(pulses)))
        take += current.period + (0 if current.grid else delay)
    return pulses


#: Delays generated per (re)start: more pulses than any run `simulate` is asked for.
_SEQUENCE_CHUNK = 1 << 16
