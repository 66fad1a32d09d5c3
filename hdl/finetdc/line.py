"""The delay lines: chains of ECP5 carry cells the hit runs along side by side, sampled at every
clock edge."""

from amaranth.hdl import C, Cat, Instance, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from . import LINE_TAPS, LINES


__all__ = ["is_ecp5", "CARRY_BOX", "CARRY_BOX_FILE", "SCRIPT_AFTER_SYNTH", "DelayLine"]


def is_ecp5(platform):
    """Whether ``platform`` builds for an ECP5 (Amaranth's Lattice platforms say so in
    ``family``); the simulators and the other families have no carry chain to use."""
    return getattr(platform, "family", None) == "ecp5"


#: The carry cells' type while yosys synthesises: an opaque box. Yosys knows what a ``CCU2C``
#: computes, and to it every tap is the same function of the hit (a delay line is, logically, a
#: wire): it would drive all the flip-flops from the hit and leave the chain unconnected. The
#: box hides that; :data:`SCRIPT_AFTER_SYNTH` gives the cells their real type for nextpnr.
CARRY_BOX = "FLISS_CCU2C"
#: The box's declaration, a Verilog file for the platform to read before synthesis.
CARRY_BOX_FILE = ("fliss_carry_box.v", f"""(* blackbox *)
module {CARRY_BOX} (input CIN, input A0, input B0, input C0, input D0, input A1, input B1,
                    input C1, input D1, output S0, output S1, output COUT);
  parameter [15:0] INIT0 = 16'h0000;
  parameter [15:0] INIT1 = 16'h0000;
  parameter INJECT1_0 = "YES";
  parameter INJECT1_1 = "YES";
endmodule
""")
#: Yosys commands after synthesis (the platform's ``script_after_synth``): the boxes become
#: ``CCU2C`` cells.
SCRIPT_AFTER_SYNTH = f"chtype -set CCU2C t:{CARRY_BOX}"

# A CCU2C half passes its carry in to its carry out when its LUT4 reads 1 (INIT all ones), and
# its sum output is then the carry in inverted. The first half of the first cell injects the
# hit instead: its LUT4 reads 0 (C0 = D0 = 1 select INIT0[15:12], all zero) and its carry out
# is its LUT2, INIT0[{B0, A0}] = A0, the hit.
_PROPAGATE = 0xFFFF
_INJECT = 0x000A


class DelayLine(wiring.Component):
    """Tapped delay lines side by side, sampled into flip-flops at every clock edge, then once more.

    On an ECP5 (:func:`is_ecp5`; the platform must run :data:`SCRIPT_AFTER_SYNTH` after
    synthesis, and reads :data:`CARRY_BOX_FILE`, which this block adds) the hit enters each of
    ``lines`` chains of ``CCU2C`` carry cells through the chain's first cell's first half; every
    later half is one tap (8.4 or 62.5 ps in nextpnr's timing model of the routed line, in turn),
    its sum output sampled by a flip-flop at every rising clock edge (the *first stage*: tap
    ``j`` reads 1 once the hit has reached it), then by a second flip-flop against
    metastability. Each chain is a carry chain of its own, placed apart, so the routes from the
    hit to their first cells differ and their taps interleave. On any other platform (Amaranth's
    simulator, Verilator, other families) there is no chain: the first stage is the ``sampled``
    port, for a testbench to drive from the model
    (:meth:`fliss.sim.models.finetdc.Line.samples`). Either way, the first stage of cycle ``c``
    is on ``taps`` in cycle ``c + 1``.

    Parameters
    ----------
    taps : int
        Taps of each line, at least 2 (:data:`~fliss.hdl.finetdc.LINE_TAPS` by default).
    lines : int
        Lines, at least 1 (:data:`~fliss.hdl.finetdc.LINES` by default).

    Members
    -------
    hit : In(1)
        The hit, asynchronous (ECP5 only).
    sampled : In(lines * taps)
        The first stage (not on an ECP5).
    taps : Out(lines * taps)
        The second stage: tap ``j`` of line ``k`` is bit ``k * taps + j``, nearest the input
        first.
    """

    def __init__(self, taps=LINE_TAPS, lines=LINES):
        if isinstance(taps, bool) or not isinstance(taps, int) or taps < 2:
            raise ValueError(f"A delay line needs at least 2 taps, not {taps!r}")
        if isinstance(lines, bool) or not isinstance(lines, int) or lines < 1:
            raise ValueError(f"The fine TDC needs at least one delay line, not {lines!r}")
        self.count = taps
        self.lines = lines
        width = lines * taps
        super().__init__({"hit": In(1), "sampled": In(width), "taps": Out(width)})

    def elaborate(self, platform):
        m = Module()

        if is_ecp5(platform):
            if CARRY_BOX_FILE[0] not in platform.extra_files:
                platform.add_file(*CARRY_BOX_FILE)
            # The chains, then the first stage beside them: the sums are the carries inverted
            sums = []
            for line in range(self.lines):
                sums += self._chain(m, line)
            sampled = Signal(len(sums), attrs={"keep": 1})
            m.d.sync += sampled.eq(Cat(sums))
            first_stage = ~sampled
        else:
            first_stage = self.sampled

        # Second stage
        m.d.sync += self.taps.eq(first_stage)

        return m

    def _chain(self, m, line):
        # Line `line`'s cells, `line{line}_{cell}`: cell 0's second half is tap 0, cell k's halves
        # taps 2k - 1 and 2k. Returns the taps' sum outputs in order.
        sums = []
        carry = C(0)
        for cell in range(self.count // 2 + 1):
            first = cell == 0
            name = f"line{line}_{cell}"
            s0, s1, cout = Signal(name=f"{name}_s0"), Signal(name=f"{name}_s1"), \
                Signal(name=f"{name}_carry")
            m.submodules[name] = Instance(
                CARRY_BOX,
                p_INIT0=C(_INJECT if first else _PROPAGATE, 16),
                p_INIT1=C(_PROPAGATE, 16),
                p_INJECT1_0="NO", p_INJECT1_1="NO",
                a_keep=1,
                i_CIN=carry,
                i_A0=self.hit if first else C(0), i_B0=C(0),
                i_C0=C(int(first)), i_D0=C(int(first)),
                i_A1=C(0), i_B1=C(0), i_C1=C(0), i_D1=C(0),
                o_S0=s0, o_S1=s1, o_COUT=cout)
            sums += [s1] if first else [s0, s1]
            carry = cout
        return sums[:self.count]
