"""Formal harnesses of the delay core: laser trigger, pulse scheduler, delay sources, LFSR."""

from amaranth.hdl import Assert, Assume, Cover, Module, ResetSignal, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from fliss.hdl.laser import LaserTrigger

from .runner import Proof


# Laser trigger

class _LateStartTrigger(wiring.Component):
    """Mutant: a laser trigger whose TDC start comes one cycle after the laser's rising edge."""

    def __init__(self, *, width_bits):
        self._width_bits = width_bits
        super().__init__({"fire": In(1), "width": In(width_bits), "laser": Out(1),
                          "tdc_start": Out(1)})

    def elaborate(self, platform):
        m = Module()
        m.submodules.trigger = trigger = LaserTrigger(width_bits=self._width_bits)
        m.d.comb += [trigger.fire.eq(self.fire), trigger.width.eq(self.width),
                     self.laser.eq(trigger.laser)]
        m.d.sync += self.tdc_start.eq(trigger.tdc_start)
        return m


class TriggerHarness(wiring.Component):
    """The laser trigger alone, with ``fire`` and ``width`` free: the TDC start strobes in the
    cycle of every rising edge of the laser, and only while the laser is on."""

    fire:  In(1)
    width: In(3)

    def __init__(self, trigger=LaserTrigger):
        self._trigger = trigger
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.trigger = trigger = self._trigger(width_bits=3)
        m.d.comb += [trigger.fire.eq(self.fire), trigger.width.eq(self.width)]
        m.d.comb += Assume(~ResetSignal())

        laser_d = Signal()
        m.d.sync += laser_d.eq(trigger.laser)
        rise = trigger.laser & ~laser_d
        m.d.comb += [
            Assert(~rise | trigger.tdc_start),
            Assert(~trigger.tdc_start | trigger.laser),
            Cover(rise),
        ]
        return m


PROOFS = [
    Proof("delay_core.trigger_start", TriggerHarness, "prove", 2,
          "laser trigger: a TDC start in every rising edge's cycle, and only while the laser is on",
          mutant=lambda: TriggerHarness(_LateStartTrigger)),
]
