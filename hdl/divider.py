"""Serial divider: an unsigned quotient and remainder, one quotient bit per clock cycle."""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out


__all__ = ["SerialDivider"]


class SerialDivider(wiring.Component):
    """Restoring division: ``dividend // divisor`` and ``dividend % divisor``.

    ``start`` loads the operands; ``quotient_bits`` cycles later ``busy`` falls and ``quotient``
    and ``remainder`` hold the result until the next ``start``. The quotient must fit in
    ``quotient_bits`` (``dividend < divisor << quotient_bits``): the caller makes sure of it.
    A zero divisor gives a quotient of all ones.

    Parameters
    ----------
    dividend_bits, divisor_bits, quotient_bits : int
        Widths of the operands and of the quotient.

    Members
    -------
    start : In(1)
        Load ``dividend`` and ``divisor`` and begin.
    dividend : In(dividend_bits)
    divisor : In(divisor_bits)
    busy : Out(1)
        A division is in progress (from the cycle after ``start``).
    quotient : Out(quotient_bits)
    remainder : Out(divisor_bits)
    """

    def __init__(self, dividend_bits, divisor_bits, quotient_bits):
        for name, value in (("Dividend", dividend_bits), ("Divisor", divisor_bits),
                            ("Quotient", quotient_bits)):
            if not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} width must be a positive integer, not {value!r}")
        self.quotient_bits = quotient_bits
        super().__init__({
            "start":     In(1),
            "dividend":  In(dividend_bits),
            "divisor":   In(divisor_bits),
            "busy":      Out(1),
            "quotient":  Out(quotient_bits),
            "remainder": Out(divisor_bits),
        })

    def elaborate(self, platform):
        m = Module()

        # The dividend's low bits shift out of `low` as the quotient bits shift in.
        rem = Signal(len(self.divisor) + 1)
        low = Signal(self.quotient_bits)
        divisor = Signal.like(self.divisor)
        steps = Signal(range(self.quotient_bits + 1))
        trial = Cat(low[-1], rem)
        fits = trial >= divisor
        with m.If(self.start):
            m.d.sync += [
                rem.eq(self.dividend >> self.quotient_bits),
                low.eq(self.dividend),
                divisor.eq(self.divisor),
                steps.eq(self.quotient_bits),
            ]
        with m.Elif(steps != 0):
            m.d.sync += [
                rem.eq(Mux(fits, trial - divisor, trial)),
                low.eq(Cat(fits, low[:-1])),
                steps.eq(steps - 1),
            ]
        m.d.comb += [
            self.busy.eq(steps != 0),
            self.quotient.eq(low),
            self.remainder.eq(rem),
        ]

        return m
