"""What drives the delay line: the photon pin, the on-chip oscillator, or a trigger output's pad
read back."""

from amaranth.hdl import ClockDomain, ClockSignal, Instance, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from . import HitInput
from .line import is_ecp5


__all__ = ["OSCILLATOR_DIV", "OSCILLATOR_BOX_FILE", "HitSource"]


#: Divider of the ECP5's internal oscillator (``OSCG``, nominally 310 MHz): about 2.4 MHz, high
#: and low some 200 ns each, longer than the line, so that the line empties between its hits.
OSCILLATOR_DIV = 128

#: A declaration of the ECP5's ``OSCG`` (its ports and parameter as the ECP5 library has them),
#: for tools that read the Verilog of a top level with the fine TDC without the ECP5 library
#: (a lint, a simulation): a Verilog file, name and text. Its output stays undriven there.
OSCILLATOR_BOX_FILE = ("ecp5_oscg.v", """(* blackbox *)
module OSCG (output OSC);
  parameter DIV = 128;
endmodule
""")


class HitSource(wiring.Component):
    """The input of the fine TDC's delay line, selected by ``select``.

    The uncorrelated source (ECP5 only; elsewhere it reads 0) is the ECP5's internal oscillator
    ``OSCG``, a ring oscillator in the silicon, nominally 310 MHz divided by
    :data:`OSCILLATOR_DIV` (the datasheet allows it 15 % either way): some 2.4 MHz, against the
    80 to 100 MHz clock from the board's crystal, unrelated to it. Its phase against the clock
    drifts with its jitter and temperature: over many hits, uniform, as the code-density
    calibration needs. (A ring of LUTs in the fabric would do the same, but nextpnr refuses to
    analyse the timing of a design with a combinational loop.) The multiplexer is
    combinational (LUTs in front of the line: a fixed delay for each input).

    The internal loopback (``LASER``, ``AGGRESSOR``) takes a trigger output's pad as its input
    buffer reads it back (a bidirectional pad with its output always enabled, made by
    :class:`~fliss.boards.BoardTop` for a design input named after the output with ``_pad``):
    the output's edge after the output buffer, the pad and the input buffer, a fixed delay.

    Nothing clocked by the design clock may drive the line: nextpnr has no false paths, and a
    flip-flop's path through the 14 ns line would be timed against the clock period. So the
    selection is taken through a flip-flop clocked by the oscillator (a setting that stays put:
    no synchroniser needed). The pads break the trigger's path: in nextpnr's ECP5 timing model
    (``ecp5/arch.cc``, ``Arch::getPortTimingClass``) a pad's (``TRELLIS_IO``) output ``I`` and
    enable ``T`` are endpoints and its input ``O`` a startpoint, and ``Arch::getCellDelay``
    gives it no arc from ``I`` to ``O``: the trigger's flip-flop is timed to the pad only, and
    the path from the pad into the line starts unclocked (``<async>``), outside the Fmax.

    Members
    -------
    pin : In(1)
        The photon pin, asynchronous.
    laser, aggressor : In(1)
        The victim's laser output and the aggressor's trigger output, their pads read back.
    select : In(HitInput)
    hit : Out(1)
        To the delay line.
    """

    pin:       In(1)
    laser:     In(1)
    aggressor: In(1)
    select:    In(HitInput)
    hit:       Out(1)

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
        inputs = {HitInput.PIN: self.pin, HitInput.OSCILLATOR: oscillator,
                  HitInput.LASER: self.laser, HitInput.AGGRESSOR: self.aggressor}
        with m.Switch(select):
            for value, signal in inputs.items():
                with m.Case(value):
                    m.d.comb += self.hit.eq(signal)

        return m
