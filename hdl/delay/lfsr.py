from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from .settings import MIN_LENGTH, MAX_LENGTH

__all__ = ["POLYNOMIALS", "MIN_LENGTH", "MAX_LENGTH", "Lfsr"]


#: Primitive characteristic polynomial for each register length ``L``, written as an integer whose
#: bit ``i`` is the coefficient of ``x**i`` (bit ``L`` and bit 0 are always set).
#:
#: Each entry is the lowest-weight primitive polynomial of its degree (a trinomial where one
#: exists, a pentanomial otherwise), the one with the smallest middle exponents among those.
#: ``tests/gateware/test_lfsr.py`` proves every entry primitive.
#:
#: The register is a Galois (right-shifting) LFSR: ``state' = (state >> 1) ^ (poly >> 1)`` when the
#: bit shifted out is 1, else ``state' = state >> 1``. Read as a polynomial ``S(x)``, the state is
#: multiplied by ``x**-1`` modulo ``P(x)`` at each step, so every non-zero state is visited once
#: per period of ``2**L - 1`` steps.
POLYNOMIALS = {
    2:  0x7,         # x^2 + x + 1
    3:  0xb,         # x^3 + x + 1
    4:  0x13,        # x^4 + x + 1
    5:  0x25,        # x^5 + x^2 + 1
    6:  0x43,        # x^6 + x + 1
    7:  0x83,        # x^7 + x + 1
    8:  0x187,       # x^8 + x^7 + x^2 + x + 1
    9:  0x211,       # x^9 + x^4 + 1
    10: 0x409,       # x^10 + x^3 + 1
    11: 0x805,       # x^11 + x^2 + 1
    12: 0x1107,      # x^12 + x^8 + x^2 + x + 1
    13: 0x2027,      # x^13 + x^5 + x^2 + x + 1
    14: 0x5007,      # x^14 + x^12 + x^2 + x + 1
    15: 0x8003,      # x^15 + x + 1
    16: 0x1100b,     # x^16 + x^12 + x^3 + x + 1
    17: 0x20009,     # x^17 + x^3 + 1
    18: 0x40081,     # x^18 + x^7 + 1
    19: 0x80027,     # x^19 + x^5 + x^2 + x + 1
    20: 0x100009,    # x^20 + x^3 + 1
    21: 0x200005,    # x^21 + x^2 + 1
    22: 0x400003,    # x^22 + x + 1
    23: 0x800021,    # x^23 + x^5 + 1
    24: 0x1000087,   # x^24 + x^7 + x^2 + x + 1
    25: 0x2000009,   # x^25 + x^3 + 1
    26: 0x4000047,   # x^26 + x^6 + x^2 + x + 1
    27: 0x8000027,   # x^27 + x^5 + x^2 + x + 1
    28: 0x10000009,  # x^28 + x^3 + 1
    29: 0x20000005,  # x^29 + x^2 + 1
    30: 0x40800007,  # x^30 + x^23 + x^2 + x + 1
    31: 0x80000009,  # x^31 + x^3 + 1
    32: 0x100400007, # x^32 + x^22 + x^2 + x + 1
}


def _galois_step(state, taps):
    # One step of the right-shifting Galois register; `taps` is `poly >> 1`.
    return (state >> 1) ^ Mux(state[0], taps, 0)


def _galois_steps(state, taps, steps):
    # `steps` steps of the right-shifting Galois register with constant `taps` (an int): the
    # steps compose into a linear map over GF(2), so each bit of the result is the XOR of some
    # bits of `state`, built as one balanced XOR per bit (a chain of `steps` steps would be
    # `steps` levels of logic deep).
    columns = []            # the result for each single state bit set
    for bit in range(len(state)):
        value = 1 << bit
        for _ in range(steps):
            value = (value >> 1) ^ (taps if value & 1 else 0)
        columns.append(value)
    return Cat(Cat(state[bit] for bit, column in enumerate(columns) if column >> out & 1).xor()
               for out in range(len(state)))


class Lfsr(wiring.Component):
    """Galois linear feedback shift register.

    The register never holds zero: a seed whose low ``L`` bits are all zero loads as 1.

    Parameters
    ----------
    length : int or None
        Register length ``L`` in bits, from 2 to 32. ``None`` makes the length a run-time port.
    steps : int
        Register steps taken per ``advance``, unrolled into one clock cycle. Only a fixed-length
        register can take more than one step.

    Members
    -------
    length : In(range(2, 33))
        Present only when the length is a run-time setting. Sampled on ``load``; a value out of
        range acts as 32.
    seed : In(32)
        Initial state; its low ``L`` bits are used.
    load : In(1)
        Load the seed (and the length) in this cycle. Takes priority over ``advance``.
    advance : In(1)
        Take ``steps`` steps in this cycle.
    state : Out(32)
        Current state, zero above bit ``L - 1``.
    """

    def __init__(self, *, length=None, steps=1):
        if length is not None and (not isinstance(length, int) or
                                   not MIN_LENGTH <= length <= MAX_LENGTH):
            raise TypeError(f"Length must be None or an integer from {MIN_LENGTH} to "
                            f"{MAX_LENGTH}, not {length!r}")
        if not isinstance(steps, int) or steps < 1:
            raise TypeError(f"Steps must be a positive integer, not {steps!r}")
        if length is None and steps != 1:
            raise ValueError(f"Only a fixed-length register can take {steps} steps per advance")
        self._length = length
        self._steps = steps
        members = {
            "seed":    In(MAX_LENGTH),
            "load":    In(1),
            "advance": In(1),
            "state":   Out(MAX_LENGTH),
        }
        if length is None:
            members["length"] = In(range(MIN_LENGTH, MAX_LENGTH + 1))
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()

        state = Signal(MAX_LENGTH, init=1)
        m.d.comb += self.state.eq(state)

        # Taps of the register length latched on the last load, and the mask of the incoming
        # length for the seed: constants, or two tables. Neither depends on `load` itself, which
        # only selects between the seed and the stepped state (for timing).
        if self._length is None:
            length = Signal.like(self.length, init=MAX_LENGTH)
            with m.If(self.load):
                m.d.sync += length.eq(self.length)
            taps = Signal(MAX_LENGTH)
            mask = Signal(MAX_LENGTH)
            with m.Switch(length):
                for bits, poly in POLYNOMIALS.items():
                    with m.Case(bits):
                        m.d.comb += taps.eq(poly >> 1)
                with m.Default():
                    m.d.comb += taps.eq(POLYNOMIALS[MAX_LENGTH] >> 1)
            with m.Switch(self.length):
                for bits in POLYNOMIALS:
                    with m.Case(bits):
                        m.d.comb += mask.eq((1 << bits) - 1)
                with m.Default():
                    m.d.comb += mask.eq(-1)
        else:
            taps = POLYNOMIALS[self._length] >> 1
            mask = Const((1 << self._length) - 1, MAX_LENGTH)

        # Next state
        with m.If(self.load):
            seeded = self.seed & mask
            m.d.sync += state.eq(Mux(seeded == 0, 1, seeded))
        with m.Elif(self.advance):
            if self._length is None:
                m.d.sync += state.eq(_galois_step(state, taps))
            else:
                m.d.sync += state.eq(_galois_steps(state, taps, self._steps))

        return m
