"""What drives the delay line: the photon pin, an on-chip ring oscillator, or the laser trigger."""

from amaranth.hdl import C, ClockDomain, ClockSignal, Instance, Module, Signal
from amaranth.lib import enum, wiring
from amaranth.lib.wiring import In, Out

from .line import is_ecp5


__all__ = ["HitInput", "RING_STAGES", "RING_DIVIDER_BITS", "HitSource"]


class HitInput(enum.Enum, shape=2):
    """The fine TDC's input (register ``tdc_input``)."""
    #: The photon pin (a SPAD module's pulses).
    PIN = 0
    #: The on-chip ring oscillator, divided: hits uncorrelated with the clock, for the
    #: code-density calibration with no light.
    RING = 1
    #: The victim's laser trigger, looped back inside: a self-test with no jumper (hits at a
    #: fixed phase of the clock, so one code).
    LASER = 2


#: LUTs in the ring: one gated inverter and buffers (an odd number of inversions).
RING_STAGES = 15
#: The ring's output is divided by ``2**RING_DIVIDER_BITS`` before it drives the line, so that
#: the line empties between its hits.
RING_DIVIDER_BITS = 4

# LUT4 truth tables, indexed by {D, C, B, A}: Z = ~A & B (inverter gated by B), Z = A (buffer)
_GATED_INVERTER = 0x4444
_BUFFER = 0xAAAA


class HitSource(wiring.Component):
    """The input of the fine TDC's delay line, selected by ``select``.

    The ring oscillator (ECP5 only; elsewhere it reads 0) is :data:`RING_STAGES` LUTs in a loop,
    kept through synthesis, running only while selected. Each LUT and its route take roughly
    0.5 to 0.8 ns, so the ring runs at some 40 to 65 MHz, below the 80 MHz clock and unrelated to
    it; divided by ``2**RING_DIVIDER_BITS`` it gives hits at some 3 to 4 MHz, high and low
    about 150 ns each, longer than the line, so that the line empties between hits. Its phase
    against the clock drifts with the ring's jitter and temperature: over many hits, uniform, as
    the code-density calibration needs. The multiplexer is combinational (one LUT in front of
    the line: a fixed delay, the same for every hit).

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

        # Ring oscillator and its divider
        ring = Signal()
        if is_ecp5(platform):
            enable = Signal()
            m.d.sync += enable.eq(self.select == HitInput.RING)
            nodes = [Signal(name=f"ring_{k}", attrs={"keep": 1}) for k in range(RING_STAGES)]
            for k, node in enumerate(nodes):
                m.submodules[f"ring_{k}"] = Instance(
                    "LUT4", p_INIT=C(_GATED_INVERTER if k == 0 else _BUFFER, 16), a_keep=1,
                    i_A=nodes[k - 1], i_B=enable if k == 0 else C(0), i_C=C(0), i_D=C(0),
                    o_Z=node)
            m.domains.ring = ClockDomain("ring", local=True, reset_less=True)
            divider = Signal(RING_DIVIDER_BITS)
            m.d.comb += ClockSignal("ring").eq(nodes[-1])
            m.d.ring += divider.eq(divider + 1)
            m.d.comb += ring.eq(divider[-1])

        # Selection
        with m.Switch(self.select):
            with m.Case(HitInput.PIN):
                m.d.comb += self.hit.eq(self.pin)
            with m.Case(HitInput.RING):
                m.d.comb += self.hit.eq(ring)
            with m.Case(HitInput.LASER):
                m.d.comb += self.hit.eq(self.laser)

        return m
