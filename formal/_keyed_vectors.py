"""Harness ``keyed.trivium_vectors``: the gateware's Trivium (``hdl/delay/trivium.py``, at the
keyed source's ``KEYED_ROUNDS`` bits a cycle), loaded in its first cycle with a known key and IV,
gives the published keystream: eSTREAM set 1 vector 0 (key ``80 00 … 00``, IV 0, bytes 0 to 15).
(The model, ``fliss.sim.models.trivium``, is a layer above ``formal``; the simulations hold the
gateware to it for other keys and IVs, ``tests/test_keyed.py``.) Its ``ready`` rises exactly 1152 / ``KEYED_ROUNDS`` cycles after
the load. Bounded: the initialisation and :data:`CHECKED` cycles of keystream."""

from amaranth.hdl import Assert, Assume, Const, Cover, Module, ResetSignal, Signal
from amaranth.lib import wiring

from ..hdl.delay.settings import KEYED_ROUNDS
from ..hdl.delay.trivium import INIT_ROUNDS, TriviumCore
from ._harness import assigned


__all__ = ["CHECKED", "VECTORS_DEPTH", "TriviumVectorHarness"]


#: eSTREAM Trivium set 1 vector 0 (key 80 00 … 00, IV 0): keystream bytes 0 to 15.
SET_1_VECTOR_0 = bytes.fromhex("38EB86FF730D7A9CAF8DF13A4420540D")
#: Cycles of keystream checked after the initialisation (the published vector's 128 bits).
CHECKED = 8 * len(SET_1_VECTOR_0) // KEYED_ROUNDS
#: Cycles from the load to the first keystream bits.
INIT_CYCLES = INIT_ROUNDS // KEYED_ROUNDS
#: BMC depth: the load, the initialisation, the keystream checked, and a cycle to spare.
VECTORS_DEPTH = INIT_CYCLES + CHECKED + 3


def _published_bits():
    return [(SET_1_VECTOR_0[i // 8] >> (i % 8)) & 1 for i in range(8 * len(SET_1_VECTOR_0))]


#: (key, IV, the first keystream bits) of each Trivium of the harness.
CASES = [(0x80000000000000000000, 0, _published_bits())]


class _MistappedTrivium(TriviumCore):
    """Trivium loaded with ``c`` = 0b011 instead of 0b111 (one bit of the constant)."""

    def elaborate(self, platform):
        m = super().elaborate(platform)
        c, = assigned(m, "c")
        with m.If(self.load):
            m.d.sync += c.eq(Const(0b011, len(c)))
        return m


def _mistapped_trivium(rounds):
    return _MistappedTrivium(rounds=rounds)


class TriviumVectorHarness(wiring.Component):
    """Each case's Trivium loaded in the first cycle, then moved on in every cycle; the
    keystream checked cycle by cycle against the case's bits."""

    def __init__(self, *, mutate=None):
        self.make = mutate or (lambda rounds: TriviumCore(rounds=rounds))
        super().__init__({})

    def elaborate(self, platform):
        m = Module()
        m.d.comb += Assume(~ResetSignal())
        cycle = Signal(range(VECTORS_DEPTH + 2))     # cycles since the first, saturating
        with m.If(cycle != VECTORS_DEPTH + 1):
            m.d.sync += cycle.eq(cycle + 1)
        for n, (key, iv, bits) in enumerate(CASES):
            trivium = self.make(KEYED_ROUNDS)
            m.submodules[f"trivium_{n}"] = trivium
            m.d.comb += [trivium.key.eq(key), trivium.iv.eq(iv), trivium.load.eq(cycle == 0),
                         trivium.next.eq(1)]
            # the keystream from cycle `INIT_CYCLES + 1` on, `KEYED_ROUNDS` bits a cycle
            for k in range(CHECKED):
                word = sum(bit << j for j, bit in enumerate(bits[k * KEYED_ROUNDS:
                                                                 (k + 1) * KEYED_ROUNDS]))
                with m.If(cycle == INIT_CYCLES + 1 + k):
                    m.d.comb += Assert(trivium.z == word)
            with m.If(cycle != 0):
                m.d.comb += Assert(trivium.ready == (cycle > INIT_CYCLES))
        m.d.comb += Cover(cycle == INIT_CYCLES + CHECKED)
        return m
