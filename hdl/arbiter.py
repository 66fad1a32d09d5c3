from amaranth.hdl import *
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from .framing import PacketBeat


__all__ = ["PacketArbiter"]


class PacketArbiter(wiring.Component):
    """Merges packet streams into one, a whole packet at a time, and numbers the packets.

    At a packet boundary the lowest-numbered input with a packet waiting wins, so replies to
    commands (input 0) never queue behind a histogram. Each packet leaves with the next sequence
    number (modulo 256) in its header.

    Parameters
    ----------
    count : int
        Number of inputs, at least 1.

    Members
    -------
    i : In(stream.Signature(PacketBeat)).array(count)
        Packet streams, in priority order.
    o : Out(stream.Signature(PacketBeat))
        Merged, numbered packets.
    """

    def __init__(self, count):
        if not isinstance(count, int) or count < 1:
            raise TypeError(f"Input count must be a positive integer, not {count!r}")
        self.count = count
        super().__init__({
            "i": In(stream.Signature(PacketBeat)).array(count),
            "o": Out(stream.Signature(PacketBeat)),
        })

    def elaborate(self, platform):
        m = Module()

        seq = Signal(8)
        busy = Signal()
        grant = Signal(range(self.count))

        # Choice at a packet boundary
        choice = Signal.like(grant)
        for index in reversed(range(self.count)):
            with m.If(self.i[index].valid):
                m.d.comb += choice.eq(index)
        current = Mux(busy, grant, choice)

        for index, port in enumerate(self.i):
            with m.If(current == index):
                m.d.comb += [
                    self.o.valid.eq(port.valid),
                    self.o.payload.eq(port.payload),
                    port.ready.eq(self.o.ready),
                ]
        m.d.comb += self.o.p.header.seq.eq(seq)

        with m.If(self.o.valid & self.o.ready):
            m.d.sync += busy.eq(~self.o.p.last), grant.eq(current)
            with m.If(self.o.p.last):
                m.d.sync += seq.eq(seq + 1)

        return m
