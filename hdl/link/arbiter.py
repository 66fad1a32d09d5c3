from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from .buffer import StreamBuffer
from .framing import PacketBeat


__all__ = ["PacketArbiter"]


class PacketArbiter(wiring.Component):
    """Merges packet streams into one, a whole packet at a time, and numbers the packets.

    At a packet boundary the lowest-numbered input with a packet waiting wins, so replies to
    commands (input 0) never queue behind a histogram. Each packet leaves with the next sequence
    number (modulo 256) in its header. The output is registered (a :class:`StreamBuffer`), so no
    combinational path runs from the inputs to the consumer. It passes a beat every other cycle
    at most (a half-rate buffer, half the flip-flops): the UART behind it is far slower.

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

        m.submodules.buffer = buffer = StreamBuffer(PacketBeat, full_rate=False)
        wiring.connect(m, buffer.o, wiring.flipped(self.o))
        merged = buffer.i

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
                    merged.valid.eq(port.valid),
                    merged.payload.eq(port.payload),
                    port.ready.eq(merged.ready),
                ]
        m.d.comb += merged.p.header.seq.eq(seq)

        with m.If(merged.valid & merged.ready):
            m.d.sync += busy.eq(~merged.p.last), grant.eq(current)
            with m.If(merged.p.last):
                m.d.sync += seq.eq(seq + 1)

        return m
