"""Bit-exact model of :class:`fliss.hdl.delay.aggressor.Aggressor`.

The aggressor is a pulse scheduler and laser trigger whose enable rises ``offset`` cycles after
the common ``enable``; :func:`fliss.sim.models.scheduler.simulate` models it with the enable shifted.
"""

import numpy as np

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.delay.aggressor import OFFSET_WIDTH, PAPER_OFFSET_S
from ...hdl.delay.laser import LATENCY
from . import scheduler as _scheduler


__all__ = ["PAPER_OFFSET_S", "offset_cycles", "simulate", "laser_waveform"]


def offset_cycles(offset_s=PAPER_OFFSET_S, clock_hz=DEFAULT_CLOCK_HZ):
    """Start offset in clock cycles: ``round(offset_s * clock_hz)``; 6 for 75 ns at 80 MHz."""
    if not offset_s >= 0:
        raise ValueError(f"Aggressor offset must be zero or positive, not {offset_s!r} s")
    cycles = round(offset_s * clock_hz)
    if cycles >= (1 << OFFSET_WIDTH):
        raise ValueError(f"Aggressor offset of {offset_s!r} s is longer than "
                         f"{(1 << OFFSET_WIDTH) - 1} clock cycles")
    return cycles


def simulate(settings, until, *, offset, enable=0, disable=None, updates=()):
    """Aggressor pulses, as :func:`fliss.sim.models.scheduler.simulate` returns them.

    ``settings`` (a :class:`fliss.sim.models.scheduler.Settings`) are those present when the aggressor
    starts, in cycle ``enable + offset``; ``updates`` are ``update`` strobes after that.
    """
    if not isinstance(offset, (int, np.integer)) or not 0 <= offset < (1 << OFFSET_WIDTH):
        raise ValueError(f"Aggressor offset must be from 0 to {(1 << OFFSET_WIDTH) - 1} "
                         f"clock cycles, not {offset!r}")
    if disable is not None and disable <= enable + offset:
        return []
    return _scheduler.simulate(settings, until, updates=updates, enable=enable + offset,
                               disable=disable)


def laser_waveform(pulses, cycles):
    """``laser`` in cycles ``0 … cycles - 1``: high ``width`` cycles from ``fire + LATENCY``."""
    laser = np.zeros(cycles, dtype=bool)
    for fire, _, width, _ in pulses:
        laser[fire + LATENCY:fire + LATENCY + max(width, 1)] = True
    return laser
