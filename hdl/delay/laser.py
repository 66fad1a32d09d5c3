from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from .settings import PULSE_WIDTH_WIDTH


__all__ = ["LATENCY", "LaserTrigger"]


#: Cycles from ``fire`` to the laser's rising edge and the TDC start strobe.
LATENCY = 1


class LaserTrigger(wiring.Component):
    """Laser trigger and TDC start.

    A ``fire`` strobe in cycle ``t`` raises ``laser`` for cycles ``t + 1 … t + width`` and
    strobes ``tdc_start`` in cycle ``t + 1``, the cycle of the laser's rising edge: the TDC
    starts with the same (delayed) pulse, so the delay cancels out of the victim's timestamps
    (equation 5 of the paper). Both outputs come straight from flip-flops.

    Parameters
    ----------
    width_bits : int
        Width of ``width``, in bits.

    Members
    -------
    fire : In(1)
        Fire a pulse.
    width : In(width_bits)
        Pulse width in clock cycles, sampled with ``fire``; zero acts as one.
    laser : Out(1)
        Laser trigger output.
    tdc_start : Out(1)
        TDC start strobe, one cycle long.
    """

    def __init__(self, *, width_bits=PULSE_WIDTH_WIDTH):
        if not isinstance(width_bits, int) or width_bits < 1:
            raise ValueError(f"Pulse width bits must be a positive integer, not {width_bits!r}")
        super().__init__({
            "fire":      In(1),
            "width":     In(width_bits),
            "laser":     Out(1),
            "tdc_start": Out(1),
        })

    def elaborate(self, platform):
        m = Module()

        remaining = Signal.like(self.width)
        m.d.sync += self.tdc_start.eq(self.fire)
        with m.If(self.fire):
            m.d.sync += [
                self.laser.eq(1),
                remaining.eq(Mux(self.width == 0, 0, self.width - 1)),
            ]
        with m.Elif(remaining != 0):
            m.d.sync += remaining.eq(remaining - 1)
        with m.Else():
            m.d.sync += self.laser.eq(0)

        return m
