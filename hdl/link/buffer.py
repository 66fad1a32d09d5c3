from amaranth.hdl import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out


__all__ = ["StreamBuffer"]


class StreamBuffer(wiring.Component):
    """Register slice for a stream: cuts every combinational path through it.

    ``o.valid``, ``o.payload`` and ``i.ready`` all come from registers, so the paths of the
    producer end here and those of the consumer start here. At full rate, a second register (the
    *skid* register) takes the one transfer that ``i`` makes while ``o`` stalls, so the buffer
    still moves one transfer per cycle. At half rate there is no skid register: ``i`` is ready
    only while the output register is empty, so the buffer moves at most one transfer every two
    cycles, and the payload enters its register with no multiplexer in front (for a producer
    whose payload comes late, such as a block RAM's output, feeding a slow consumer). A payload
    entering in cycle ``t`` leaves at the earliest in cycle ``t + 1``; order is kept and nothing
    is dropped.

    Parameters
    ----------
    shape : shape-like
        Payload shape.
    full_rate : bool
        One transfer per cycle (the default), or at most one every two cycles.

    Members
    -------
    i : In(stream.Signature(shape))
    o : Out(stream.Signature(shape))
    """

    def __init__(self, shape, *, full_rate=True):
        if not isinstance(full_rate, bool):
            raise TypeError(f"full_rate must be True or False, not {full_rate!r}")
        self.full_rate = full_rate
        super().__init__({
            "i": In(stream.Signature(shape)),
            "o": Out(stream.Signature(shape)),
        })

    def elaborate(self, platform):
        m = Module()

        if not self.full_rate:
            m.d.comb += self.i.ready.eq(~self.o.valid)
            with m.If(self.o.valid):
                with m.If(self.o.ready):
                    m.d.sync += self.o.valid.eq(0)
            with m.Elif(self.i.valid):
                m.d.sync += [self.o.valid.eq(1), self.o.payload.eq(self.i.payload)]
            return m

        skid_valid = Signal()
        skid = Signal.like(self.i.payload)
        m.d.comb += self.i.ready.eq(~skid_valid)

        with m.If(~self.o.valid | self.o.ready):
            # The output register is free in the next cycle: fill it, from the skid first.
            with m.If(skid_valid):
                m.d.sync += [self.o.valid.eq(1), self.o.payload.eq(skid), skid_valid.eq(0)]
            with m.Else():
                m.d.sync += [self.o.valid.eq(self.i.valid), self.o.payload.eq(self.i.payload)]
        with m.Elif(self.i.valid & ~skid_valid):
            m.d.sync += [skid_valid.eq(1), skid.eq(self.i.payload)]

        return m
