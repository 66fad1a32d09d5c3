"""Trivium keystream generator in gateware, several rounds per clock cycle.

The state and its loading are those of the model, :mod:`fliss.sim.models.trivium` (the eSTREAM
reference code's): registers ``a`` (``s1 … s93``), ``b`` (``s94 … s177``) and ``c``
(``s178 … s288``), the highest-numbered bit of each at bit 0. Up to 64 rounds read only bits of
the state before them (no tap is nearer than 66 rounds to a register's input), so ``rounds``
rounds are one layer of logic per new bit.
"""

from amaranth.hdl import Cat, Const, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from .settings import KEY_BITS, IV_BITS


__all__ = ["INIT_ROUNDS", "TriviumCore"]


#: Rounds run after loading, before the first keystream bit (4 × 288).
INIT_ROUNDS = 4 * 288


def _byte_reversed(value):
    """The reference code's number from the 80-bit integer of the printed bytes."""
    return Cat(value[8 * k:8 * k + 8] for k in reversed(range(len(value) // 8)))


class TriviumCore(wiring.Component):
    """Trivium (80-bit key and IV), ``rounds`` keystream bits per clock cycle.

    Parameters
    ----------
    rounds : int
        Rounds per cycle: a divisor of 1152 from 1 to 64.

    Members
    -------
    key : In(80)
    iv : In(80)
        The key and IV as the 80-bit integers their printed bytes spell (as in
        :mod:`fliss.sim.models.trivium`), sampled on ``load``.
    load : In(1)
        Load the key and IV and run the 1152 initialisation rounds, ``1152 / rounds`` cycles.
    ready : Out(1)
        Initialised: ``z`` holds keystream bits. Low from the cycle after ``load``.
    z : Out(rounds)
        The next ``rounds`` keystream bits, the first at bit 0.
    next : In(1)
        Move on to the next ``rounds`` bits (while ``ready``; ignored otherwise).
    """

    def __init__(self, *, rounds):
        if not isinstance(rounds, int) or not 1 <= rounds <= 64 or INIT_ROUNDS % rounds:
            raise ValueError(f"Trivium rounds per cycle must be a divisor of {INIT_ROUNDS} from "
                             f"1 to 64, not {rounds!r}")
        self.rounds = rounds
        super().__init__({
            "key":   In(KEY_BITS),
            "iv":    In(IV_BITS),
            "load":  In(1),
            "ready": Out(1),
            "z":     Out(rounds),
            "next":  In(1),
        })

    def elaborate(self, platform):
        m = Module()
        n = self.rounds

        a = Signal(93)
        b = Signal(84)
        c = Signal(111)

        # The next `n` rounds, from the state as it is (bit i of each term is round i + 1)
        def taps(register, first, count=n):
            return register[first:first + count]

        t1 = taps(a, 27) ^ taps(a, 0)
        t2 = taps(b, 15) ^ taps(b, 0)
        t3 = taps(c, 45) ^ taps(c, 0)
        m.d.comb += self.z.eq(t1 ^ t2 ^ t3)
        f1 = t1 ^ (taps(a, 2) & taps(a, 1)) ^ taps(b, 6)    # into b
        f2 = t2 ^ (taps(b, 2) & taps(b, 1)) ^ taps(c, 24)   # into c
        f3 = t3 ^ (taps(c, 2) & taps(c, 1)) ^ taps(a, 24)   # into a

        # Initialisation: `INIT_ROUNDS / n` steps counted down after the load
        steps = INIT_ROUNDS // n
        count = Signal(range(steps + 1))
        m.d.comb += self.ready.eq(count == 0)

        with m.If(self.load):
            m.d.sync += [
                a.eq(_byte_reversed(self.key) << 13),
                b.eq(_byte_reversed(self.iv) << 4),
                c.eq(Const(0b111, 111)),
                count.eq(steps),
            ]
        with m.Elif((count != 0) | self.next):
            m.d.sync += [
                a.eq(Cat(a[n:], f3)),
                b.eq(Cat(b[n:], f1)),
                c.eq(Cat(c[n:], f2)),
            ]
            with m.If(count != 0):
                m.d.sync += count.eq(count - 1)

        return m
