"""DEPTH packets: the records of a frame, stored as they come, sent after a header."""

from amaranth.hdl import Module, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from .. import lookup
from ..block_ram import RegisteredRam
from ..link.framing import PacketBeat
from ..protocol import (PacketType, DepthHeader, DepthRecord, DEPTH_HEADER_BYTES,
                        DEPTH_RECORD_BYTES, DEPTH_PIXELS)


__all__ = ["DepthPacketizer"]


_PIXEL_BITS = (DEPTH_PIXELS - 1).bit_length()


class DepthPacketizer(wiring.Component):
    """Stores up to :data:`~fliss.hdl.protocol.DEPTH_PIXELS` records (a block RAM with a
    registered read, :class:`~fliss.hdl.block_ram.RegisteredRam`) and sends them as one DEPTH
    packet.

    ``write`` stores ``record`` as the frame's next pixel. ``send`` (while not ``busy``) takes
    ``header`` and sends the packet: its header beat, the :class:`DepthHeader` bytes, then the
    first ``2**header.pixel_bits`` records, 7 bytes each, little-endian; the next ``write``
    stores pixel 0 again.

    Members
    -------
    write : In(1)
    record : In(DepthRecord)
    send : In(1)
    header : In(DepthHeader)
    busy : Out(1)
        A packet is being sent (from the cycle after ``send``).
    packets : Out(stream.Signature(PacketBeat))
    """

    write:   In(1)
    record:  In(DepthRecord)
    send:    In(1)
    header:  In(DepthHeader)
    busy:    Out(1)
    packets: Out(stream.Signature(PacketBeat))

    def elaborate(self, platform):
        m = Module()

        m.submodules.records = records = RegisteredRam(
            depth=DEPTH_PIXELS, width=data.Layout.cast(DepthRecord).size)

        header = Signal(DepthHeader)
        pixel = Signal(range(DEPTH_PIXELS + 1))
        byte = Signal(range(max(DEPTH_HEADER_BYTES, DEPTH_RECORD_BYTES)))
        word = Signal(DEPTH_RECORD_BYTES * 8)
        pixels = lookup([1 << p for p in range(_PIXEL_BITS + 1)], header.pixel_bits)
        length = lookup([DEPTH_HEADER_BYTES + (1 << p) * DEPTH_RECORD_BYTES
                         for p in range(_PIXEL_BITS + 1)], header.pixel_bits, 16)
        m.d.comb += [
            self.packets.p.header.type.eq(PacketType.DEPTH),
            self.packets.p.header.length.eq(length),
            records.read_addr.eq(pixel),
            records.read_en.eq(1),
        ]
        # A record's write is registered (the block RAM may sit far away) and lands a cycle
        # later, long before the records are read (after HEADER and PREFIX)
        m.d.sync += [
            records.write_addr.eq(pixel),
            records.write_data.eq(self.record),
            records.write_en.eq(0),
        ]

        with m.FSM():
            with m.State("STORE"):
                m.d.sync += records.write_en.eq(self.write)
                with m.If(self.write):
                    m.d.sync += pixel.eq(pixel + 1)
                with m.If(self.send):
                    m.d.sync += header.eq(self.header)
                    m.next = "HEADER"

            with m.State("HEADER"):
                m.d.comb += [self.busy.eq(1),
                             self.packets.valid.eq(1), self.packets.p.first.eq(1)]
                with m.If(self.packets.ready):
                    m.d.sync += [byte.eq(0), pixel.eq(0)]
                    m.next = "PREFIX"

            with m.State("PREFIX"):
                m.d.comb += [self.busy.eq(1), self.packets.valid.eq(1),
                             self.packets.p.data.eq(header.as_value().word_select(byte, 8))]
                with m.If(self.packets.ready):
                    m.d.sync += byte.eq(byte + 1)
                    with m.If(byte == DEPTH_HEADER_BYTES - 1):
                        m.d.sync += byte.eq(0)
                        m.next = "FETCH"

            # The record memory gives the word two cycles after its address
            with m.State("FETCH"):
                m.d.comb += self.busy.eq(1)
                m.next = "SETTLE"

            with m.State("SETTLE"):
                m.d.comb += self.busy.eq(1)
                m.next = "LOAD"

            with m.State("LOAD"):
                m.d.comb += self.busy.eq(1)
                m.d.sync += word.eq(records.read_data)
                m.next = "RECORD"

            with m.State("RECORD"):
                final = (byte == DEPTH_RECORD_BYTES - 1) & (pixel == pixels - 1)
                m.d.comb += [self.busy.eq(1), self.packets.valid.eq(1),
                             self.packets.p.data.eq(word[:8]),
                             self.packets.p.last.eq(final)]
                with m.If(self.packets.ready):
                    m.d.sync += [byte.eq(byte + 1), word.eq(word >> 8)]
                    with m.If(byte == DEPTH_RECORD_BYTES - 1):
                        m.d.sync += [byte.eq(0), pixel.eq(pixel + 1)]
                        m.next = "FETCH"
                    with m.If(final):
                        m.d.sync += pixel.eq(0)
                        m.next = "STORE"

        return m
