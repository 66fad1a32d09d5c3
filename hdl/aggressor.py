"""Aggressor emitter: a second laser trigger with its own period, offset and delays."""

from amaranth.hdl import *
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from .core import DelayCore
from .delay import DelayMode, DELAY_WIDTH, MAX_MASK_WIDTH
from .lfsr import MAX_LENGTH
from .scheduler import PERIOD_WIDTH, PULSE_WIDTH_WIDTH


__all__ = ["OFFSET_WIDTH", "PAPER_OFFSET_S", "Aggressor"]


#: Width of the start offset setting, in bits.
OFFSET_WIDTH = 32

#: Start offset of the aggressor in the paper's experiments, in seconds (6 cycles at 80 MHz).
PAPER_OFFSET_S = 75e-9


class Aggressor(wiring.Component):
    """Aggressor emitter.

    A second illuminator trigger driven by the same FPGA, as on the paper's bench: a
    :class:`~fliss.hdl.core.DelayCore` of its own, whose delay source is used only with
    ``delay_source`` (otherwise it stays ``OFF``). It
    starts ``offset`` cycles after ``enable`` rises: if ``enable`` rises in cycle ``e``, the
    aggressor's scheduler sees its enable rise in cycle ``e + offset``. With the victim's delay
    core enabled in the same cycle, the same period and no delays on either side, each aggressor
    pulse is exactly ``offset`` cycles after the matching victim pulse. ``enable`` falling stops
    the aggressor at once (a pulse already firing completes); the offset counts again from the
    next rise. ``offset`` is sampled while ``enable`` is low; the other settings behave as in
    :class:`~fliss.hdl.core.DelayCore`. (If ``enable`` is already high in the first cycle after
    reset, the aggressor starts one cycle late; a register file never does that.)

    Parameters
    ----------
    delay_source : bool
        Give the aggressor its own delay source (ports ``mode``, ``length``, ``mask_width``,
        ``seed``). Without it, the aggressor fires on its nominal schedule only.

    Members
    -------
    enable : In(1)
        Run; normally the victim's enable.
    update : In(1)
        Sample new settings while running.
    offset : In(32)
        Start offset in clock cycles.
    period : In(32)
    grid : In(1)
    pulse_width : In(16)
        Scheduler settings (:class:`~fliss.hdl.scheduler.PulseScheduler`).
    mode : In(DelayMode)
    length : In(range(2, 33))
    mask_width : In(range(1, 17))
    seed : In(32)
        Delay source settings (:class:`~fliss.hdl.delay.DelaySource`), with ``delay_source``.
    laser : Out(1)
        Aggressor's laser trigger output.
    running : Out(1)
    fire : Out(1)
    fire_delay : Out(32)
    pulse_index : Out(32)
        Monitor outputs of the aggressor's scheduler.
    """

    def __init__(self, *, delay_source=True):
        if not isinstance(delay_source, bool):
            raise TypeError(f"delay_source must be True or False, not {delay_source!r}")
        self.delay_source = delay_source
        ports = {
            "enable":      In(1),
            "update":      In(1),
            "offset":      In(OFFSET_WIDTH),
            "period":      In(PERIOD_WIDTH),
            "grid":        In(1),
            "pulse_width": In(PULSE_WIDTH_WIDTH),
        }
        if delay_source:
            ports.update({
                "mode":       In(DelayMode),
                "length":     In(range(2, MAX_LENGTH + 1)),
                "mask_width": In(range(1, MAX_MASK_WIDTH + 1)),
                "seed":       In(MAX_LENGTH),
            })
        ports.update({
            "laser":       Out(1),
            "running":     Out(1),
            "fire":        Out(1),
            "fire_delay":  Out(DELAY_WIDTH),
            "pulse_index": Out(32),
        })
        super().__init__(ports)

    def elaborate(self, platform):
        m = Module()

        m.submodules.core = core = DelayCore()

        # Start offset: a countdown loaded with `offset` while stopped. `arrived` is registered,
        # so no comparator sits in front of the scheduler. `primed` marks the cycles after the
        # first one: the countdown is loaded at least once before it is used.
        primed = Signal()
        countdown = Signal(OFFSET_WIDTH)
        arrived = Signal()
        started = Signal()
        m.d.sync += primed.eq(1)
        with m.If(~self.enable | ~primed):
            m.d.sync += countdown.eq(self.offset), arrived.eq(self.offset == 0)
        with m.Elif(~arrived):
            m.d.sync += countdown.eq(countdown - 1), arrived.eq(countdown == 1)
        m.d.comb += started.eq(self.enable & primed & arrived)

        # Delay source, scheduler and trigger: a delay core of its own
        if self.delay_source:
            m.d.comb += [
                core.mode.eq(self.mode),
                core.length.eq(self.length),
                core.mask_width.eq(self.mask_width),
                core.seed.eq(self.seed),
            ]
        else:
            m.d.comb += core.mode.eq(DelayMode.OFF)
        m.d.comb += [
            core.enable.eq(started),
            core.update.eq(self.update),
            core.period.eq(self.period),
            core.grid.eq(self.grid),
            core.pulse_width.eq(self.pulse_width),

            self.laser.eq(core.laser),
            self.running.eq(core.running),
            self.fire.eq(core.fire),
            self.fire_delay.eq(core.fire_delay),
            self.pulse_index.eq(core.pulse_index),
        ]

        return m
