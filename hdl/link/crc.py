"""The link's CRC-16 as stream stages: one appends it to packets, one checks and removes it.

The CRC is CRC-16/IBM-3740 (:data:`~fliss.hdl.protocol.CRC_POLY`,
:data:`~fliss.hdl.protocol.CRC_INIT`), sent most significant byte first, so that the CRC of a
whole packet, CRC included, is zero. :data:`LINK_CRC` describes it for :mod:`amaranth.lib.crc`;
:func:`fliss.protocol.crc16` is the software model.

The engine is our own :class:`Crc16` rather than :class:`amaranth.lib.crc.Processor`: the two
compute the same function, but the library's engine restarts through a multiplexer in front of
its XOR network, which cost 22 logic cells on the iCE40UP5K for the two engines of the link (see
``docs/boards.md``). :data:`LINK_CRC` stays the reference the tests hold the engine to.
"""

from amaranth.hdl import Array, Cat, Module, Signal, Value
from amaranth.lib import crc as lib_crc, data, stream, wiring
from amaranth.lib.wiring import In, Out

from .cobs import PacketByte, CobsVerdict, DecodedByte
from ..protocol import CRC_WIDTH, CRC_POLY, CRC_INIT, CRC_BYTES


__all__ = ["LINK_CRC", "crc16_next", "Crc16", "CheckedByte", "CrcAppender", "CrcChecker"]


#: The link's CRC-16/IBM-3740 as an :class:`amaranth.lib.crc.Algorithm` (the catalogue's
#: ``CRC16_IBM_3740``).
LINK_CRC = lib_crc.Algorithm(crc_width=CRC_WIDTH, polynomial=CRC_POLY, initial_crc=CRC_INIT,
                             reflect_input=False, reflect_output=False, xor_output=0)


def _next_bits(crc, byte):
    # The software step (most significant bit first), on integers.
    for bit in reversed(range(8)):
        feedback = (crc >> (CRC_WIDTH - 1) ^ byte >> bit) & 1
        crc = ((crc << 1) & ((1 << CRC_WIDTH) - 1)) ^ (CRC_POLY if feedback else 0)
    return crc


#: The step as a matrix over GF(2): bit ``j`` of the next CRC is the parity of the bits of
#: ``Cat(crc, byte)`` that ``_MASKS[j]`` selects (the step is linear in the CRC and the byte).
_MASKS = [sum(1 << i for i in range(CRC_WIDTH + 8)
              if _next_bits((1 << i) & ((1 << CRC_WIDTH) - 1), (1 << i) >> CRC_WIDTH) >> j & 1)
          for j in range(CRC_WIDTH)]


def crc16_next(crc, byte):
    """CRC after one more byte: ``crc`` (16 bits) and ``byte`` (8 bits) are Amaranth values.

    The byte is processed most significant bit first with :data:`~fliss.hdl.protocol.CRC_POLY`,
    as CRC-16/IBM-3740 does. The result is a combinational expression: each bit the parity of
    the input bits it depends on (one reduction a bit, which simulators evaluate far faster than
    the network of single XOR gates a bit-serial description gives).
    """
    bits = Cat(Value.cast(crc), Value.cast(byte))
    return Cat(*((bits & mask).xor() for mask in _MASKS))


class Crc16(wiring.Component):
    """CRC-16/IBM-3740 generator and checker, one byte per cycle.

    Members
    -------
    clear : In(1)
        Restart from :data:`~fliss.hdl.protocol.CRC_INIT`; the byte on ``data`` is ignored.
    valid : In(1)
        Add the byte on ``data``.
    data : In(8)
        Byte to add.
    crc : Out(16)
        CRC of the bytes added since the last ``clear``, from the next cycle. Send it most
        significant byte first; after its two bytes are added too, ``crc`` is zero.
    """

    clear: In(1)
    valid: In(1)
    data:  In(8)
    crc:   Out(CRC_WIDTH, init=CRC_INIT)

    def elaborate(self, platform):
        m = Module()
        with m.If(self.clear):
            m.d.sync += self.crc.eq(CRC_INIT)
        with m.Elif(self.valid):
            m.d.sync += self.crc.eq(crc16_next(self.crc, self.data))
        return m


class CheckedByte(data.Struct):
    """A byte of a packet with its CRC removed (``end`` low), or the end of a frame (``end``
    high) with what the COBS decoder and the CRC check found."""
    data:    8
    end:     1
    verdict: CobsVerdict
    #: With ``end``: fewer bytes than the CRC itself.
    short:   1
    #: With ``end``: the CRC of the frame, CRC included, is not zero.
    bad_crc: 1


class CrcAppender(wiring.Component):
    """Appends the CRC to each packet.

    Cut-through: the packet's bytes pass with no latency (``last`` cleared), then the two CRC
    bytes, most significant first, the second with ``last``. The CRC restarts after each packet.

    Members
    -------
    i : In(stream.Signature(PacketByte))
        Packets.
    o : Out(stream.Signature(PacketByte))
        Packets with their CRC.
    """

    i: In(stream.Signature(PacketByte))
    o: Out(stream.Signature(PacketByte))

    def elaborate(self, platform):
        m = Module()

        m.submodules.engine = engine = Crc16()
        m.d.comb += engine.data.eq(self.i.p.data)

        index = Signal(range(CRC_BYTES))
        crc_bytes = Array(engine.crc.word_select(k, 8) for k in reversed(range(CRC_BYTES)))
        with m.FSM():
            with m.State("DATA"):
                m.d.comb += [
                    self.o.valid.eq(self.i.valid),
                    self.o.p.data.eq(self.i.p.data),
                    self.i.ready.eq(self.o.ready),
                ]
                with m.If(self.i.valid & self.i.ready):
                    m.d.comb += engine.valid.eq(1)
                    with m.If(self.i.p.last):
                        m.next = "CRC"
            with m.State("CRC"):
                m.d.comb += [
                    self.o.valid.eq(1),
                    self.o.p.data.eq(crc_bytes[index]),
                    self.o.p.last.eq(index == CRC_BYTES - 1),
                ]
                with m.If(self.o.ready):
                    m.d.sync += index.eq(index + 1)
                    with m.If(self.o.p.last):
                        m.d.sync += index.eq(0)
                        m.d.comb += engine.clear.eq(1)
                        m.next = "DATA"

        return m


class CrcChecker(wiring.Component):
    """Checks the CRC of each frame and removes it.

    Cut-through, with no latency on the frame ends: ``i.ready`` is ``o.ready``. The last
    :data:`~fliss.hdl.protocol.CRC_BYTES` bytes of a frame wait in a delay line, so that each
    byte leaves when the byte :data:`~fliss.hdl.protocol.CRC_BYTES` places after it arrives,
    and the CRC never leaves. A frame end passes at once, with ``short`` and ``bad_crc`` added
    to the COBS decoder's verdict; then the CRC restarts.

    Members
    -------
    i : In(stream.Signature(DecodedByte))
        Decoded bytes and frame ends, from a :class:`~fliss.hdl.link.cobs.CobsDecoder`.
    o : Out(stream.Signature(CheckedByte))
        Packet bytes and frame ends, checked.
    """

    i: In(stream.Signature(DecodedByte))
    o: Out(stream.Signature(CheckedByte))

    def elaborate(self, platform):
        m = Module()

        m.submodules.engine = engine = Crc16()

        held = Signal(range(CRC_BYTES + 1))     # bytes in the delay line, saturating
        delay = Signal(8 * CRC_BYTES)           # the last CRC_BYTES bytes, oldest first
        take = Signal()
        m.d.comb += [
            self.i.ready.eq(self.o.ready),
            take.eq(self.i.valid & self.i.ready),
            engine.data.eq(self.i.p.data),
            engine.valid.eq(take & ~self.i.p.end),
            engine.clear.eq(take & self.i.p.end),
            self.o.valid.eq(self.i.valid & (self.i.p.end | (held == CRC_BYTES))),
            self.o.p.end.eq(self.i.p.end),
            self.o.p.verdict.eq(self.i.p.verdict),
            self.o.p.short.eq(held != CRC_BYTES),
            self.o.p.bad_crc.eq(engine.crc != 0),
        ]
        with m.If(~self.i.p.end):
            m.d.comb += self.o.p.data.eq(delay[:8])
        with m.If(take):
            with m.If(self.i.p.end):
                m.d.sync += held.eq(0)
            with m.Else():
                m.d.sync += delay.eq(Cat(delay[8:], self.i.p.data))
                with m.If(held != CRC_BYTES):
                    m.d.sync += held.eq(held + 1)

        return m
