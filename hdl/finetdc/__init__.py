"""A fine TDC in the FPGA fabric: a tapped delay line of carry cells, sampled at every clock edge.

One block per module:

* :mod:`.line`: :class:`~.line.DelayLine`, :data:`LINES` carry chains side by side and their two
  flip-flop stages (on the ECP5), or the sampled taps from a port (simulation, other families);
* :mod:`.encoder`: :class:`~.encoder.Encoder`, ones count of all the lines' sampled taps (the raw
  code) and the cycle a hit arrives;
* :mod:`.table`: :class:`~.table.CalibrationTable`, raw code -> fine time, in block RAM, written
  by the host;
* :mod:`.source`: :class:`~.source.HitSource`, what drives the line (:class:`HitInput`: the
  photon pin, the on-chip oscillator, or a trigger output's pad read back);
* :mod:`.tdc`: :class:`~.tdc.FineTdc`, all of it with the coarse count since the TDC start,
  giving :class:`~fliss.hdl.tdc.Capture` records.

The numbers below describe the hardware; the model (:mod:`fliss.sim.models.finetdc`) and the
host read them from here.
"""


from amaranth.lib import enum

from ..event import TDC_LSB_S


__all__ = ["HitInput", "LINES", "LINE_TAPS", "TAPS", "LINE_TAP_S", "TAP_S", "CODE_BITS",
           "TABLE_BITS", "UNIT_S", "LSB_SELECTS", "POPCOUNT_FANIN", "popcount_stages", "LATENCY",
           "lsb_s"]


class HitInput(enum.Enum, shape=2):
    """The fine TDC's input (register ``tdc_input``)."""
    #: The photon pin (a SPAD module's pulses).
    PIN = 0
    #: The ECP5's on-chip oscillator: hits uncorrelated with the clock, for the code-density
    #: calibration with no light.
    OSCILLATOR = 1
    #: The victim's laser output, its pad read back: the self-test with no jumper wire.
    LASER = 2
    #: The aggressor's trigger output, its pad read back: the self-test of the victim's delays
    #: with no jumper wire.
    AGGRESSOR = 3


#: Delay lines the hit runs along side by side, each its own carry chain. The raw code is the sum
#: of their ones counts: their taps interleave, so a code is on average a tap over ``LINES``.
LINES = 2
#: Mean delay of a tap in nextpnr's timing model of the routed ULX3S line: 8.4 ps from a
#: ``CCU2C``'s first half to its second, 62.5 ps from a cell to the next one.
LINE_TAP_S = 35.5e-12
#: Taps of each line: 201 ``CCU2C`` cells (the first injects the hit), 14.2 ns at
#: :data:`LINE_TAP_S`: the board's 12.5 ns clock period (80 MHz, 352 taps) with 14 % margin,
#: a 10 ns one (100 MHz) with 42 %.
LINE_TAPS = 400
#: Taps of all the lines, the sampled bits the ones count reads: raw codes are 0 to ``TAPS``.
TAPS = LINES * LINE_TAPS
#: Nominal width of a raw code (a tap of the lines merged): :data:`LINE_TAP_S` over
#: :data:`LINES`. The calibration table's reset values and the raw codes' unit on the host.
TAP_S = LINE_TAP_S / LINES
#: Width of a raw code (0 to :data:`TAPS`): the calibration table has ``2**CODE_BITS`` entries.
CODE_BITS = TAPS.bit_length()
#: Width of a calibration table entry, in :data:`UNIT_S` units (up to 51 ns).
TABLE_BITS = 12
#: The table's unit: the finest timestamp LSB.
UNIT_S = TDC_LSB_S / 4
#: The timestamp LSBs on offer (register ``fine_lsb``): ``TDC_LSB_S / 2**k`` for ``k`` in
#: 0, 1, 2 (50, 25 and 12.5 ps; 409.6, 204.8 and 102.4 ns of range).
LSB_SELECTS = 3
#: Sampled taps summed per pipeline stage of the ones count.
POPCOUNT_FANIN = 8


def popcount_stages(taps=TAPS):
    """Pipeline stages of the ones count of ``taps`` bits."""
    stages, width = 0, taps
    while width > 1:
        width = -(-width // POPCOUNT_FANIN)
        stages += 1
    return stages


#: Cycles from the cycle the line's first flip-flops hold a hit's first non-zero taps to the
#: cycle its capture is presented: the second flip-flop stage, the ones count, the table read
#: and its output register, the subtraction of the fine time, and the output register.
LATENCY = 1 + popcount_stages() + 4


def lsb_s(select):
    """The timestamp LSB of ``fine_lsb`` = ``select``, in seconds."""
    return TDC_LSB_S / (1 << select)
