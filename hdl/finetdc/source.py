"""What drives the delay line: the photon pin or the on-chip oscillator."""

from amaranth.hdl import ClockDomain, ClockSignal, Instance, Module, Mux, Signal
from amaranth.lib import enum, wiring
from amaranth.lib.wiring import In, Out

from .line import is_ecp5


__all__ = ["HitInput", "OSCILLATOR_DIV", "HitSource"]


class HitInput(enum.Enum, shape=1):
    """The fine TDC's input (register ``tdc_input``)."""
    #: The photon pin (a SPAD module's pulses).
    PIN = 0
    #: The ECP5's on-chip oscillator: hits uncorrelated with the clock, for the code-density
    #: calibration with no light.
    OSCILLATOR = 1


#: Divider of the ECP5's internal oscillator (``OSCG``, nominally 310 MHz): about 2.4 MHz, high
#: and low some 200 ns each, longer than the line, so that the line empties between its hits.
OSCILLATOR_DIV = 128


class HitSource(wiring.Component):
    """The input of the fine TDC's delay line, selected by ``select``.

    The uncorrelated source (ECP5 only; elsewhere it reads 0) is the ECP5's internal oscillator
    ``OSCG``, a ring oscillator in the silicon, nominally 310 MHz divided by
    :data:`OSCILLATOR_DIV` (the datasheet allows it 15 % either way): some 2.4 MHz, against the
    80 to 100 MHz clock from the board's crystal, unrelated to it. Its phase against the clock
    drifts with its jitter and temperature: over many hits, uniform, as the code-density
    calibration needs. (A ring of LUTs in the fabric would do the same, but nextpnr refuses to
    analyse the timing of a design with a combinational loop.) The multiplexer is
    combinational (a LUT in front of the line: a fixed delay, the same for every hit).

    Nothing clocked by the design clock may drive the line: nextpnr has no false paths, and a
    flip-flop's path through the 14 ns line would be timed against the clock period. So the
    selection is taken through a flip-flop clocked by the oscillator (a setting that stays put:
    no synchroniser needed), and there is no loopback of the laser trigger (it would need the
    laser pin's pad read back through its input buffer).

    Members
    -------
    pin : In(1)
        The photon pin, asynchronous.
    select : In(HitInput)
    hit : Out(1)
        To the delay line.
    """

    pin:    In(1)
    select: In(HitInput)
    hit:    Out(1)

    def elaborate(self, platform):
        m = Module()

        # The on-chip oscillator, and the selection in its clock domain
        oscillator = Signal()
        select = Signal(HitInput)
        if is_ecp5(platform):
            m.submodules.oscillator = Instance("OSCG", p_DIV=OSCILLATOR_DIV, o_OSC=oscillator)
            m.domains.oscillator = ClockDomain("oscillator", local=True, reset_less=True)
            m.d.comb += ClockSignal("oscillator").eq(oscillator)
            m.d.oscillator += select.eq(self.select)
        else:
            m.d.comb += select.eq(self.select)

        # Selection
        m.d.comb += self.hit.eq(Mux(select == HitInput.OSCILLATOR, oscillator, self.pin))

        return m
