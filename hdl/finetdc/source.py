"""What drives the delay line: the photon pin, the on-chip oscillator, or the laser trigger."""

from amaranth.hdl import Instance, Module, Signal
from amaranth.lib import enum, wiring
from amaranth.lib.wiring import In, Out

from .line import is_ecp5


__all__ = ["HitInput", "OSCILLATOR_DIV", "HitSource"]


class HitInput(enum.Enum, shape=2):
    """The fine TDC's input (register ``tdc_input``)."""
    #: The photon pin (a SPAD module's pulses).
    PIN = 0
    #: The ECP5's on-chip oscillator: hits uncorrelated with the clock, for the code-density
    #: calibration with no light.
    OSCILLATOR = 1
    #: The victim's laser trigger, looped back inside: a self-test with no jumper (hits at a
    #: fixed phase of the clock, so one code).
    LASER = 2


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

    Members
    -------
    pin : In(1)
        The photon pin, asynchronous.
    laser : In(1)
        The victim's laser trigger.
    select : In(HitInput)
    hit : Out(1)
        To the delay line.
    """

    pin:    In(1)
    laser:  In(1)
    select: In(HitInput)
    hit:    Out(1)

    def elaborate(self, platform):
        m = Module()

        # The on-chip oscillator
        oscillator = Signal()
        if is_ecp5(platform):
            m.submodules.oscillator = Instance("OSCG", p_DIV=OSCILLATOR_DIV, o_OSC=oscillator)

        # Selection
        with m.Switch(self.select):
            with m.Case(HitInput.PIN):
                m.d.comb += self.hit.eq(self.pin)
            with m.Case(HitInput.OSCILLATOR):
                m.d.comb += self.hit.eq(oscillator)
            with m.Case(HitInput.LASER):
                m.d.comb += self.hit.eq(self.laser)

        return m
