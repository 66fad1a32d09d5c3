"""A histogram chunk as a packet: its header, then its items as they come."""

from amaranth.hdl import Cat, Mux, Module, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ..link.framing import PacketBeat
from .layout import COUNT_WIDTH
from ..protocol import (CHUNK_BINS, COMPACT_BYTES, HISTOGRAM_COUNT_BITS, HistogramChunk,
                        HistogramCompact, PacketType)


__all__ = ["CHUNK_HEADER_BYTES", "COMPACT_HEADER_BYTES", "COUNT_BYTES", "ChunkEmitter"]


#: Bytes of a chunk's header, of each count after it, and of a compact chunk's header.
CHUNK_HEADER_BYTES = data.Layout.cast(HistogramChunk).size // 8
COUNT_BYTES = HISTOGRAM_COUNT_BITS // 8
COMPACT_HEADER_BYTES = data.Layout.cast(HistogramCompact).size // 8
assert COUNT_WIDTH == HISTOGRAM_COUNT_BITS, "the readout's counts go out as they are"


class ChunkEmitter(wiring.Component):
    """Sends one histogram chunk a ``start``: the packet's header beat, the chunk's header, then
    ``size`` items taken from ``items``. A HISTOGRAM chunk is a
    :class:`~fliss.hdl.protocol.HistogramChunk` ``header`` and ``size`` counts, each a
    little-endian u16; with ``compact``, a HISTOGRAM_COMPACT chunk is a
    :class:`~fliss.hdl.protocol.HistogramCompact` ``compact_header`` and ``size`` token bytes
    (each in an item's low byte). The chunk path of both histogram packetizers
    (:class:`~fliss.hdl.packets.histogram.HistogramPacketizer` feeds it from its buffers,
    :class:`~fliss.hdl.packets.histogram_full.FullHistogramPacketizer` from the readout).

    Cycles: ``start`` is taken while idle (``busy`` low) and the header beat is offered the next
    cycle; a header byte goes in every cycle ``packets`` is ready; an item is waited for
    (``items.ready`` high, whatever ``items.valid``) after the header and after each item's
    last byte, and its bytes follow in the cycles after it is taken. ``done`` is high in the
    cycle the chunk's last byte is taken, and ``busy`` falls after it.

    Parameters
    ----------
    compact : bool
        Whether the emitter can send HISTOGRAM_COMPACT chunks too.

    Members
    -------
    start : In(1)
        Send a chunk (taken while ``busy`` is low).
    busy : Out(1)
        A chunk is being sent.
    done : Out(1)
        Strobe: the chunk's last byte is taken.
    compact : In(1)
        (With ``compact``.) The chunk is a HISTOGRAM_COMPACT chunk; held while ``busy``.
    header : In(HistogramChunk)
        The header of a HISTOGRAM chunk; held until its last byte is taken.
    compact_header : In(HistogramCompact)
        (With ``compact``.) The header of a HISTOGRAM_COMPACT chunk; held the same.
    length : In(16)
        The packet's length; held while ``busy``.
    size : In(range(CHUNK_BINS + 1)) or In(range(COMPACT_BYTES + 1))
        Items in the chunk (at least one in a HISTOGRAM chunk); held while ``busy``.
    items : In(stream.Signature(COUNT_WIDTH))
        The chunk's items, in order.
    taken : Out(range(CHUNK_BINS + 1)) or Out(range(COMPACT_BYTES + 1))
        Items taken so far in the chunk being sent (0 while idle): the index of the next.
    packets : Out(stream.Signature(PacketBeat))
    """

    def __init__(self, *, compact=False):
        self._compact = bool(compact)
        most = max(CHUNK_BINS, COMPACT_BYTES) if compact else CHUNK_BINS
        members = {
            "start":   In(1),
            "busy":    Out(1),
            "done":    Out(1),
            "header":  In(HistogramChunk),
            "length":  In(16),
            "size":    In(range(most + 1)),
            "items":   In(stream.Signature(COUNT_WIDTH)),
            "taken":   Out(range(most + 1)),
            "packets": Out(stream.Signature(PacketBeat)),
        }
        if compact:
            members.update(compact=In(1), compact_header=In(HistogramCompact))
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()

        header_bytes = COMPACT_HEADER_BYTES if self._compact else CHUNK_HEADER_BYTES
        byte = Signal(range(max(header_bytes, COUNT_BYTES)))
        item = Signal(COUNT_WIDTH)
        last_item = Signal()        # `item` is the chunk's last (registered, for timing)

        # What differs between the two kinds of chunk
        if self._compact:
            packet_type = Mux(self.compact, PacketType.HISTOGRAM_COMPACT, PacketType.HISTOGRAM)
            header_end = Mux(self.compact, COMPACT_HEADER_BYTES, CHUNK_HEADER_BYTES) - 1
            # (byte by byte, so that the multiplexer goes where both hold the same field)
            full = self.header.as_value()
            compact = self.compact_header.as_value()
            header_byte = Cat(*(Mux(self.compact, compact.word_select(index, 8),
                                    full.word_select(index, 8) if index < CHUNK_HEADER_BYTES
                                    else 0)
                                for index in range(COMPACT_HEADER_BYTES))).word_select(byte, 8)
            item_end = Mux(self.compact, 0, COUNT_BYTES - 1)
            empty = self.size == 0                  # (only a compact chunk may be)
        else:
            packet_type = PacketType.HISTOGRAM
            header_end = CHUNK_HEADER_BYTES - 1
            header_byte = self.header.as_value().word_select(byte, 8)
            item_end = COUNT_BYTES - 1
            empty = 0

        m.d.comb += [
            self.packets.p.header.type.eq(packet_type),
            self.packets.p.header.length.eq(self.length),
        ]

        with m.FSM():
            with m.State("IDLE"):
                with m.If(self.start):
                    m.next = "HEADER"

            with m.State("HEADER"):
                m.d.comb += [self.busy.eq(1), self.packets.valid.eq(1),
                             self.packets.p.first.eq(1)]
                with m.If(self.packets.ready):
                    m.d.sync += byte.eq(0)
                    m.next = "PREFIX"

            with m.State("PREFIX"):
                final = (byte == header_end) & empty
                m.d.comb += [
                    self.busy.eq(1),
                    self.packets.valid.eq(1),
                    self.packets.p.data.eq(header_byte),
                    self.packets.p.last.eq(final),
                ]
                with m.If(self.packets.ready):
                    m.d.sync += byte.eq(byte + 1)
                    with m.If(final):
                        m.d.comb += self.done.eq(1)
                        m.next = "IDLE"
                    with m.Elif(byte == header_end):
                        m.d.sync += byte.eq(0)
                        m.next = "TAKE"

            with m.State("TAKE"):
                m.d.comb += [self.busy.eq(1), self.items.ready.eq(1)]
                with m.If(self.items.valid):
                    m.d.sync += [item.eq(self.items.payload),
                                 last_item.eq(self.taken + 1 == self.size),
                                 self.taken.eq(self.taken + 1)]
                    m.next = "ITEM"

            with m.State("ITEM"):
                last_byte = byte == item_end
                m.d.comb += [
                    self.busy.eq(1),
                    self.packets.valid.eq(1),
                    self.packets.p.data.eq(item.word_select(byte[0], 8)),
                    self.packets.p.last.eq(last_byte & last_item),
                ]
                with m.If(self.packets.ready):
                    m.d.sync += byte.eq(byte + 1)
                    with m.If(last_byte):
                        m.d.sync += byte.eq(0)
                        with m.If(last_item):
                            m.d.comb += self.done.eq(1)
                            m.d.sync += self.taken.eq(0)
                            m.next = "IDLE"
                        with m.Else():
                            m.next = "TAKE"

        return m
