"""A user's own TDC: a counter of clock cycles, started by the FLISS delay core's ``tdc_start``
and stopped by a photon detector's pin.

Written for this example (it is not part of FLISS): any TDC of yours takes its place, as long as
it starts on ``tdc_start``.
"""

from amaranth.hdl import Module, Signal
from amaranth.lib import cdc, data, stream, wiring
from amaranth.lib.wiring import In, Out


__all__ = ["SYNC_STAGES", "Measurement", "measurement_layout", "CounterTdc"]


#: Flip-flops of the photon pin's synchroniser: the cycles a hit takes to be seen, which the TDC
#: takes off every time it measures.
SYNC_STAGES = 2


def measurement_layout(width):
    """Layout of one measurement: ``cycles`` from the TDC start to the photon (``width`` bits)
    and ``pulse``, the index of the laser pulse it belongs to."""
    return data.StructLayout({"cycles": width, "pulse": 32})


#: The layout of the default 12-bit TDC.
Measurement = measurement_layout(12)


class CounterTdc(wiring.Component):
    """Coarse TDC: clock cycles from the last start strobe to a photon hit.

    A hit whose pin first reads high in cycle ``p`` (sampled at the clock edge that ends it),
    after a ``start`` strobe in cycle ``s``, is measured as ``p - s`` cycles, with the pulse
    index as it is in cycle ``p +`` :data:`SYNC_STAGES` (the delay core's ``pulse_index`` then
    counts the pulse of that start, so ``pulse_index - 1`` is its index). The measurement is on
    ``measurements`` (a strobe: ``valid`` for one cycle) in cycle ``p + SYNC_STAGES + 1``.

    A hit is dropped and counted in ``dropped`` when it cannot be measured: before the first
    start, ``2**width - 1 - SYNC_STAGES`` cycles or more after the last one, or while a start
    arrives (``p < s <= p + SYNC_STAGES``: it belongs to the pulse before). The pin must stay
    high and low for at least 2 cycles each.

    Parameters
    ----------
    width : int
        Width of the counter in bits, 4 to 16: measurements of ``0 … 2**width - 2 -
        SYNC_STAGES`` cycles.

    Members
    -------
    start : In(1)
        Start strobe (the delay core's ``tdc_start``).
    hit : In(1)
        Photon detector's pin, asynchronous, active high.
    pulse_index : In(32)
        The delay core's ``pulse_index``.
    measurements : Out(stream.Signature(measurement_layout(width), always_ready=True))
        One measurement per hit measured.
    dropped : Out(16)
        Hits dropped (saturating).
    """

    def __init__(self, *, width=12):
        if not isinstance(width, int) or not 4 <= width <= 16:
            raise ValueError(f"TDC width must be an integer from 4 to 16 bits, not {width!r}")
        self.width = width
        super().__init__({
            "start":        In(1),
            "hit":          In(1),
            "pulse_index":  In(32),
            "measurements": Out(stream.Signature(measurement_layout(width),
                                                 always_ready=True)),
            "dropped":      Out(16),
        })

    def elaborate(self, platform):
        m = Module()
        top = (1 << self.width) - 1

        # Photon pin: synchronised, then its rising edge
        hit = Signal()
        hit_last = Signal()
        m.submodules.hit_sync = cdc.FFSynchronizer(self.hit, hit, stages=SYNC_STAGES)
        m.d.sync += hit_last.eq(hit)
        rise = hit & ~hit_last

        # Cycles since the start: 1 in the cycle after the strobe, up to `top` (also the value
        # before the first start)
        elapsed = Signal(self.width, init=top)
        with m.If(self.start):
            m.d.sync += elapsed.eq(1)
        with m.Elif(elapsed != top):
            m.d.sync += elapsed.eq(elapsed + 1)

        # A hit seen now rose SYNC_STAGES cycles ago: measurable after the last start, unless
        # the next one came meanwhile (`pulse_index` has then moved on)
        measurable = (elapsed >= SYNC_STAGES) & (elapsed != top) & ~self.start
        m.d.sync += self.measurements.valid.eq(rise & measurable)
        with m.If(rise):
            m.d.sync += [
                self.measurements.payload.cycles.eq(elapsed - SYNC_STAGES),
                self.measurements.payload.pulse.eq(self.pulse_index - 1),
            ]
        with m.If(rise & ~measurable & (self.dropped != 0xFFFF)):
            m.d.sync += self.dropped.eq(self.dropped + 1)

        return m
