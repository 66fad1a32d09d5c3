"""Aggressor emitter: a second laser trigger with its own period, offset and delays."""

from amaranth.hdl import Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from .core import DelayCore
from ..registers import AGGRESSOR, DelaySettings
from .settings import DELAY_WIDTH, PERIOD_WIDTH, PULSE_WIDTH_WIDTH, check_widths


__all__ = ["OFFSET_WIDTH", "PAPER_OFFSET_S", "EmitterSettings", "Aggressor"]


#: Width of the start offset setting, in bits: its register's.
OFFSET_WIDTH = AGGRESSOR.register("offset").width

#: Start offset of the aggressor in the paper's experiments, in seconds: its register's reset.
PAPER_OFFSET_S = AGGRESSOR.register("offset").reset.seconds

#: The emitter's own settings: ``enable`` (the emitter is on) and ``offset`` (start offset in
#: clock cycles); the layout of the register group :data:`~fliss.hdl.registers.AGGRESSOR`.
EmitterSettings = AGGRESSOR.layout()
assert EmitterSettings.size == 1 + OFFSET_WIDTH


class Aggressor(wiring.Component):
    """Aggressor emitter.

    A second illuminator trigger driven by the same FPGA, as on the paper's bench: a
    :class:`~fliss.hdl.delay.core.DelayCore` of its own, whose delay source is used only with
    ``delay_source`` (otherwise it stays ``OFF``). It
    runs while ``enable`` and ``emitter.enable`` are both high (call that "on"), and starts
    ``emitter.offset`` cycles after it turns on: if it turns on in cycle ``e``, the aggressor's
    scheduler sees its enable rise in cycle ``e + offset``. With the victim's delay core enabled
    in the same cycle, the same period and no delays on either side, each aggressor pulse is
    exactly ``offset`` cycles after the matching victim pulse. Turning off stops the aggressor
    at once (a pulse already firing completes); the offset counts again from the next time it
    turns on. ``offset`` is sampled while it is off; the other settings behave as in
    :class:`~fliss.hdl.delay.core.DelayCore`. (If it is already on in the first cycle after reset,
    the aggressor starts one cycle late; a register file never does that.)

    Parameters
    ----------
    delay_source : bool
        Give the aggressor its own delay source. Without it, ``settings.mode`` is zero bits wide
        and the aggressor fires on its nominal schedule only (``mode`` ``OFF``).
    period_width, pulse_width_width : int
        Widths of the ``period`` and ``pulse_width`` settings, as in
        :class:`~fliss.hdl.delay.core.DelayCore`.

    Members
    -------
    enable : In(1)
        Run; normally the victim's enable.
    update : In(1)
        Sample new settings while running.
    emitter : In(EmitterSettings)
        The emitter is on (``enable``, high by default) and its start offset in clock cycles
        (``offset``).
    settings : In(DelaySettings(..., delays=delay_source))
        Settings of the aggressor's delay core (:class:`~fliss.hdl.delay.core.DelayCore`).
    laser : Out(1)
        Aggressor's laser trigger output.
    running : Out(1)
    fire : Out(1)
    fire_delay : Out(32)
    pulse_index : Out(32)
        Monitor outputs of the aggressor's scheduler.
    """

    def __init__(self, *, delay_source=True, period_width=PERIOD_WIDTH,
                 pulse_width_width=PULSE_WIDTH_WIDTH):
        if not isinstance(delay_source, bool):
            raise TypeError(f"delay_source must be True or False, not {delay_source!r}")
        check_widths(period_width, pulse_width_width)
        self.delay_source = delay_source
        self.period_width = period_width
        self.pulse_width_width = pulse_width_width
        super().__init__({
            "enable":      In(1),
            "update":      In(1),
            "emitter":     In(EmitterSettings, init={"enable": 1}),
            "settings":    In(DelaySettings(period_width=period_width,
                                            pulse_width_width=pulse_width_width,
                                            delays=delay_source)),
            "laser":       Out(1),
            "running":     Out(1),
            "fire":        Out(1),
            "fire_delay":  Out(DELAY_WIDTH),
            "pulse_index": Out(32),
        })

    def elaborate(self, platform):
        m = Module()

        m.submodules.core = core = DelayCore(keyed=False, period_width=self.period_width,
                                             pulse_width_width=self.pulse_width_width)

        # Start offset: a countdown loaded with `offset` while off. `arrived` is registered,
        # so no comparator sits in front of the scheduler. `primed` marks the cycles after the
        # first one: the countdown is loaded at least once before it is used.
        on = self.enable & self.emitter.enable
        offset = self.emitter.offset
        primed = Signal()
        countdown = Signal(OFFSET_WIDTH)
        arrived = Signal()
        started = Signal()
        m.d.sync += primed.eq(1)
        with m.If(~on | ~primed):
            m.d.sync += countdown.eq(offset), arrived.eq(offset == 0)
        with m.Elif(~arrived):
            m.d.sync += countdown.eq(countdown - 1), arrived.eq(countdown == 1)
        m.d.comb += started.eq(on & primed & arrived)

        # Delay source, scheduler and trigger: a delay core of its own
        if self.delay_source:
            m.d.comb += core.settings.eq(self.settings)
        else:
            # (`mode` is zero bits wide here: zero-extended, it is OFF)
            m.d.comb += [core.settings[name].eq(self.settings[name])
                         for name, _ in self.settings.shape()]
        m.d.comb += [
            core.enable.eq(started),
            core.update.eq(self.update),

            self.laser.eq(core.laser),
            self.running.eq(core.running),
            self.fire.eq(core.fire),
            self.fire_delay.eq(core.fire_delay),
            self.pulse_index.eq(core.pulse_index),
        ]

        return m
