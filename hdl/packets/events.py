"""EVENTS packets: raw event batches from the raw-event FIFO."""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from ..event import Event
from ..link.framing import PacketBeat
from ..protocol import PacketType, EVENT_BYTES, MAX_EVENTS_PER_PACKET


__all__ = ["BATCH_TIMEOUT", "EventPacketizer"]

#: Cycles an incomplete event batch waits for more events before it is sent anyway.
BATCH_TIMEOUT = 1 << 14


class EventPacketizer(wiring.Component):
    """EVENTS packets from an event stream (normally a :class:`~fliss.hdl.rawfifo.RawFifo`).

    A packet holds ``n`` events, each :data:`~fliss.hdl.protocol.EVENT_BYTES` bytes of the
    :class:`~fliss.hdl.event.Event` value, little-endian. ``n`` is the FIFO ``level`` when the
    packet starts, at most :data:`~fliss.hdl.protocol.MAX_EVENTS_PER_PACKET`; a packet starts
    when a full batch is waiting, or when events have waited :data:`BATCH_TIMEOUT` cycles, or
    when ``flush`` is high (acquisition stopped).

    Members
    -------
    events : In(stream.Signature(Event))
    level : In(16)
        Events waiting behind ``events``, at least as many as will come without a gap.
    flush : In(1)
        Send what is waiting now.
    packets : Out(stream.Signature(PacketBeat))
    """

    events:  In(stream.Signature(Event))
    level:   In(16)
    flush:   In(1)
    packets: Out(stream.Signature(PacketBeat))

    def elaborate(self, platform):
        m = Module()

        count = Signal(range(MAX_EVENTS_PER_PACKET + 1))
        length = Signal.like(self.packets.p.header.length)     # of `count` events
        sent = Signal.like(count)
        byte = Signal(range(EVENT_BYTES))
        waited = Signal(range(BATCH_TIMEOUT + 1))
        word = Signal(EVENT_BYTES * 8)

        m.d.comb += [
            self.packets.p.header.type.eq(PacketType.EVENTS),
            self.packets.p.header.length.eq(length),
        ]

        with m.FSM():
            with m.State("WAIT"):
                full = self.level >= MAX_EVENTS_PER_PACKET
                with m.If(self.level == 0):
                    m.d.sync += waited.eq(0)
                with m.Elif(full | self.flush | (waited == BATCH_TIMEOUT)):
                    m.d.sync += [
                        count.eq(Mux(full, MAX_EVENTS_PER_PACKET, self.level)),
                        waited.eq(0),
                    ]
                    m.next = "LENGTH"
                with m.Else():
                    m.d.sync += waited.eq(waited + 1)

            with m.State("LENGTH"):
                # (the product from a register into a register: on an ECP5 it is a multiplier
                # block, slow enough to need its own cycle)
                m.d.sync += length.eq(count * EVENT_BYTES)
                m.next = "HEADER"

            with m.State("HEADER"):
                m.d.comb += [
                    self.packets.valid.eq(1),
                    self.packets.p.first.eq(1),
                ]
                with m.If(self.packets.ready):
                    m.d.sync += sent.eq(0), byte.eq(0)
                    m.next = "TAKE"

            with m.State("TAKE"):
                m.d.comb += self.events.ready.eq(1)
                with m.If(self.events.valid):
                    m.d.sync += word.eq(self.events.payload.as_value())
                    m.next = "BYTES"

            with m.State("BYTES"):
                last_byte = byte == EVENT_BYTES - 1
                m.d.comb += [
                    self.packets.valid.eq(1),
                    self.packets.p.data.eq(word.word_select(byte, 8)),
                    self.packets.p.last.eq(last_byte & (sent == count - 1)),
                ]
                with m.If(self.packets.ready):
                    m.d.sync += byte.eq(byte + 1)
                    with m.If(last_byte):
                        m.d.sync += byte.eq(0), sent.eq(sent + 1)
                        with m.If(sent == count - 1):
                            m.next = "WAIT"
                        with m.Else():
                            m.next = "TAKE"

        return m
