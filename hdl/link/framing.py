"""Framed, checked packets over a byte stream: the frame encoder and the frame decoder.

The format is defined in :mod:`fliss.hdl.protocol` (and described in ``docs/protocol.md``): a
packet is header, payload and CRC-16; a frame is the packet COBS-encoded, then a zero byte.
:mod:`fliss.protocol` is the software model; the tests compare the two bit for bit.

COBS rather than SLIP: the overhead is bounded (one code byte per 254 bytes, plus one, plus the
delimiter) whatever the data, where SLIP doubles every escaped byte; raw event data is not
text, so SLIP's worst case would be the link's worst case. A zero byte only ever ends a frame,
so a receiver resynchronises at the next zero whatever came before.

Packets inside the gateware travel as :class:`PacketBeat` streams: a header beat (``first``),
then one beat per payload byte; ``last`` marks the final beat (the header beat itself when the
payload is empty). Each direction is a chain of stream stages:

* out: packet beats -> bytes (:class:`FrameEncoder`) -> :class:`~.crc.CrcAppender` ->
  :class:`~.cobs.CobsEncoder` (COBS, then the delimiter);
* in: bytes -> :class:`~.cobs.CobsDecoder` -> :class:`~.crc.CrcChecker` (checks and removes the
  CRC) -> the length checks, the payload buffer and packet beats (:class:`FrameDecoder`).
"""

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ..block_ram import byte_ram, check_registered_read, reads_registered
from .buffer import StreamBuffer
from .cobs import CobsEncoder, CobsDecoder, DecodedByte
from .crc import CrcAppender, CrcChecker
from ..protocol import (Header, HEADER_BYTES, MAX_PAYLOAD, MAX_PACKET, MAX_ENCODED, CRC_BYTES,
                        NakCode, COUNTER_BITS, LINK_COUNTERS, LINK_FIELDS)


__all__ = ["PacketBeat", "FrameEncoder", "FrameDecoder"]


class PacketBeat(data.Struct):
    """One beat of a packet stream.

    ``header`` is valid in every beat of a packet. The first beat of a packet (``first`` high)
    carries no ``data``; each following beat carries one payload byte, ``header.length`` of them.
    ``last`` is high in the final beat.
    """
    header: Header
    data:   8
    first:  1
    last:   1


class FrameEncoder(wiring.Component):
    """Frame encoder: packets in, framed bytes out.

    Sends header and payload as bytes through a :class:`~.crc.CrcAppender` and a
    :class:`~.cobs.CobsEncoder`; the output is exactly :func:`fliss.protocol.encode_frame`
    of the packet. The header is sent as given: the producer sets ``length`` to the number of
    payload beats and numbers the packets (one sequence counter for everything sent on the
    link). A beat other than a header beat where a packet should start is dropped and counted in
    ``stray_beats``.

    The COBS encoder's run buffer has two banks: one run is sent from one bank while the next
    is collected in the other. Fed at one beat per cycle, the encoder only leaves a UART waiting
    when collecting a run takes longer than sending the block before it: at the start of a
    burst, or for a long run right after a short block (at most 254 cycles, less than 4
    characters at 12 Mbaud from 80 MHz).

    Members
    -------
    i : In(stream.Signature(PacketBeat))
        Packets to send.
    o : Out(stream.Signature(8))
        Frame bytes, to a :class:`~fliss.hdl.link.uart.UartTx`.
    stray_beats : Out(32)
        Beats dropped because they came where a header beat should have (wraps around).
    """

    i:           In(stream.Signature(PacketBeat))
    o:           Out(stream.Signature(8))
    stray_beats: Out(COUNTER_BITS)

    def elaborate(self, platform):
        m = Module()

        m.submodules.crc = crc = CrcAppender()
        m.submodules.cobs = cobs = CobsEncoder()
        wiring.connect(m, crc.o, cobs.i)
        wiring.connect(m, cobs.o, wiring.flipped(self.o))

        # Packet beats to bytes: the header, little-endian, then the payload
        s = crc.i
        header = Signal(Header)
        has_payload = Signal()
        index = Signal(range(HEADER_BYTES))
        with m.FSM(name="source"):
            with m.State("IDLE"):
                m.d.comb += self.i.ready.eq(1)
                with m.If(self.i.valid & self.i.payload.first):
                    m.d.sync += [
                        header.eq(self.i.payload.header),
                        has_payload.eq(~self.i.payload.last),
                        index.eq(0),
                    ]
                    m.next = "HEADER"
                with m.Elif(self.i.valid):
                    m.d.sync += self.stray_beats.eq(self.stray_beats + 1)
            with m.State("HEADER"):
                m.d.comb += [
                    s.p.data.eq(header.as_value().word_select(index, 8)),
                    s.p.last.eq(~has_payload & (index == HEADER_BYTES - 1)),
                    s.valid.eq(1),
                ]
                with m.If(s.ready):
                    m.d.sync += index.eq(index + 1)
                    with m.If(index == HEADER_BYTES - 1):
                        with m.If(has_payload):
                            m.next = "PAYLOAD"
                        with m.Else():
                            m.next = "IDLE"
            with m.State("PAYLOAD"):
                m.d.comb += [
                    s.p.data.eq(self.i.payload.data),
                    s.p.last.eq(self.i.payload.last),
                    s.valid.eq(self.i.valid),
                    self.i.ready.eq(s.ready),
                ]
                with m.If(self.i.valid & s.ready & self.i.payload.last):
                    m.next = "IDLE"

        return m


class FrameDecoder(wiring.Component):
    """Frame decoder: framed bytes in, verified packets out.

    Decodes COBS as bytes arrive (:class:`~.cobs.CobsDecoder`), checks and removes the CRC
    (:class:`~.crc.CrcChecker`), checks each frame at its delimiter and sends the packets that
    pass on ``o``. A frame that fails is dropped, counted by reason and reported on ``drop``
    and ``drop_reason``; the checks, in order:

    1. more than :data:`~fliss.hdl.protocol.MAX_ENCODED` bytes: ``OVERSIZE``;
    2. the delimiter cuts a COBS block short: ``TRUNCATED``;
    3. more than :data:`~fliss.hdl.protocol.MAX_PACKET` bytes once decoded: ``OVERSIZE``;
    4. fewer than header and CRC: ``TRUNCATED``;
    5. CRC of the whole packet not zero: ``BAD_CRC``;
    6. header ``length`` not the number of payload bytes: ``BAD_LENGTH``.

    An empty frame (two delimiters in a row) is ignored. Every delimiter starts a new frame,
    so the decoder resynchronises after any input and never wedges.

    The payload is kept in a buffer of :data:`~fliss.hdl.protocol.MAX_PAYLOAD` bytes and sent
    once the frame has been checked: a consumer never sees a byte of a frame that fails. While
    a packet is being sent, the next frame is received until six of its bytes are decoded
    (header and two more, and up to two more in the register slice before the CRC check); only
    then does ``i.ready`` fall until the packet has gone. From a
    UART at 12 Mbaud and 80 MHz (a byte every 67 cycles) that leaves over 400 cycles to read out
    a packet of at most 265 beats, so a consumer that takes a beat per cycle never stalls the
    input. The input also waits for one cycle after each delimiter, while the frame is judged.
    Every signal of ``o`` comes straight from a flip-flop.

    Parameters
    ----------
    registered_read : bool or None
        Read the payload buffer through a :class:`~fliss.hdl.block_ram.RegisteredRam`, whose
        bytes leave the block RAM from its output register (for timing on an ECP5, where a
        block RAM's plain output is slow: the ULX3S at 100 MHz), two bytes ahead and with its
        write registered; otherwise a plain memory read a byte ahead (fewer logic cells: the
        iCEBreaker). The packets are the same, cycle for cycle. ``None``: registered on an
        ECP5 platform (:func:`~fliss.hdl.block_ram.has_dp16kd`).

    Members
    -------
    i : In(stream.Signature(8))
        Frame bytes, from a :class:`~fliss.hdl.link.uart.UartRx`.
    o : Out(stream.Signature(PacketBeat))
        Verified packets.
    drop : Out(1)
        Strobe: a frame was dropped.
    drop_reason : Out(NakCode)
        Why, valid with ``drop``: ``OVERSIZE``, ``TRUNCATED``, ``BAD_CRC`` or ``BAD_LENGTH``.
    packets : Out(32)
        Packets accepted (wraps around).
    bad_crc, truncated, oversize, bad_length : Out(32)
        Frames dropped for each reason (wrap around): one counter per entry of
        :data:`~fliss.hdl.protocol.LINK_COUNTERS`.
    tally : Out(data.StructLayout)
        One strobe per drop counter above, same names: high in each cycle it counts, for
        counters elsewhere.
    """

    def __init__(self, *, registered_read=None):
        check_registered_read(registered_read)
        self.registered_read = registered_read
        super().__init__({
            "i":           In(stream.Signature(8)),
            "o":           Out(stream.Signature(PacketBeat)),
            "drop":        Out(1),
            "drop_reason": Out(NakCode, init=NakCode.BAD_CRC),
            "packets":     Out(COUNTER_BITS),
            **{name: Out(COUNTER_BITS) for name in LINK_FIELDS},
            "tally":       Out(data.StructLayout({name: 1 for name in LINK_FIELDS})),
        })

    def elaborate(self, platform):
        m = Module()

        m.submodules.cobs = cobs = CobsDecoder(max_encoded=MAX_ENCODED)
        m.submodules.crc = crc = CrcChecker()
        # A register slice between the two: the COBS decoder's block count and the CRC
        # register's enable were the slowest path of the iCEBreaker's build
        m.submodules.decoded = decoded = StreamBuffer(DecodedByte)
        wiring.connect(m, wiring.flipped(self.i), cobs.i)
        wiring.connect(m, cobs.o, decoded.i)
        wiring.connect(m, decoded.o, crc.i)
        registered = reads_registered(self.registered_read, platform)
        buffer_wr, buffer_rd = byte_ram(m, "buffer", MAX_PAYLOAD, registered,
                                        output_enable=True)

        sending = Signal()      # a checked packet is on its way out
        max_bytes = MAX_PACKET - CRC_BYTES                  # header and payload
        count = Signal(range(max_bytes + 2))                # bytes of the frame, saturating
        header = Signal(Header)

        # Input: stall when a payload byte would overwrite the packet being sent, and for the
        # cycle after each delimiter (`ending`), while the frame is judged. (`early` is
        # registered, for timing, so it holds a cycle late: it ends a byte early, as a byte in
        # that cycle may decode to one more. The CRC checker holds the last CRC_BYTES bytes
        # back, so it ends when six bytes are decoded.)
        ending = Signal()
        early = Signal(init=1)
        m.d.sync += early.eq(count < HEADER_BYTES - 1)
        m.d.comb += crc.o.ready.eq((~sending | early) & ~ending)
        take = Signal()
        end = Signal()
        m.d.comb += [
            take.eq(crc.o.valid & crc.o.ready & ~crc.o.p.end),
            end.eq(crc.o.valid & crc.o.ready & crc.o.p.end),
        ]

        # Packet bytes: the header, then the payload into the buffer at `count - HEADER_BYTES`.
        # A registered write (`registered`: the block RAM may sit far away) lands a cycle
        # later, still before the buffer is first read, in `ending`.
        write = m.d.sync if registered else m.d.comb
        write += [
            buffer_wr.addr.eq(count - HEADER_BYTES),
            buffer_wr.data.eq(crc.o.p.data),
            buffer_wr.en.eq(0),
        ]
        with m.If(take):
            with m.If(count <= max_bytes):
                m.d.sync += count.eq(count + 1)
            with m.If(count < HEADER_BYTES):
                m.d.sync += header.eq(Cat(header.as_value()[8:], crc.o.p.data))
            with m.Elif(count < max_bytes):
                write += buffer_wr.en.eq(1)

        # Verdict (see `_judge`), drawn in `ending` (the cycle after the delimiter) and
        # registered: `accept`, or `drop` with its reason; the frame state is cleared. The counters and the output follow from the
        # verdict's registers.
        m.d.sync += ending.eq(end)
        nonempty, good, reason = self._judge(m, crc.o, end, count, header)
        accept = Signal()
        sent_header = Signal(Header)    # the header of the accepted packet
        m.d.sync += [self.drop.eq(0), accept.eq(0)]
        with m.If(ending):
            m.d.sync += count.eq(0)
            with m.If(nonempty):
                with m.If(good):
                    m.d.sync += [accept.eq(1), sent_header.eq(header)]
                with m.Else():
                    m.d.sync += [
                        self.drop.eq(1),
                        self.drop_reason.eq(reason),
                    ]
        with m.If(accept):
            m.d.sync += self.packets.eq(self.packets + 1)
        with m.If(self.drop):
            with m.Switch(self.drop_reason):
                for code, name in LINK_COUNTERS.items():
                    counter = getattr(self, name)
                    with m.Case(code):
                        m.d.sync += counter.eq(counter + 1)
                        m.d.comb += getattr(self.tally, name).eq(1)

        # Output: a header beat, then the payload from the buffer; every output is a register.
        # `beat` counts beats sent. The buffer's read data holds the byte of the next beat,
        # ready to be loaded into the output when this one is taken:
        # - plain read: the buffer is read a beat ahead;
        # - registered read: the buffer is a two-stage pipeline that moves on each read, read
        #   two beats ahead, so the stage behind its read data holds the byte after. The two
        #   reads that fill it are made while the frame is judged (bytes 0 and 1, in `ending`
        #   and at `accept`: every byte is written by then). A frame can end while a packet is
        #   sent only if it is too short to pass, so its `ending` makes no read then.
        start = Signal()
        beat = Signal(range(MAX_PAYLOAD + 1))
        advance = Signal()
        m.d.comb += [
            start.eq(accept),
            advance.eq(self.o.valid & self.o.ready),
            self.o.valid.eq(sending),
        ]
        if registered:
            m.d.comb += [
                buffer_rd.en.eq((ending & ~sending) | accept | advance),
                buffer_rd.output_en.eq(buffer_rd.en),
                buffer_rd.addr.eq(Mux(sending, beat + 2, Mux(accept, 1, 0))),
            ]
        else:
            m.d.comb += buffer_rd.addr.eq(Mux(start, 0, Mux(advance, beat + 1, beat)))
        with m.If(advance):
            m.d.sync += [
                beat.eq(beat + 1),
                self.o.payload.data.eq(buffer_rd.data),
                self.o.payload.first.eq(0),
                self.o.payload.last.eq(beat + 1 == self.o.payload.header.length),
            ]
            with m.If(self.o.payload.last):
                m.d.sync += sending.eq(0)
        with m.If(start):
            m.d.sync += [
                sending.eq(1),
                beat.eq(0),
                self.o.payload.header.eq(sent_header),
                self.o.payload.data.eq(0),
                self.o.payload.first.eq(1),
                self.o.payload.last.eq(sent_header.length == 0),
            ]

        return m

    @staticmethod
    def _judge(m, checked, end, count, header):
        """The checks of a frame, in two steps for timing: at its delimiter (``end``, taken
        from the CRC checker's output ``checked``) each check is registered; in the next cycle
        the verdict is drawn from them. Returns ``nonempty`` (the frame had bytes), ``good``
        (it passed every check) and ``reason``, the :class:`NakCode` of the first check it
        failed (in the order of the class's list)."""
        nonempty = Signal()
        raw_oversize = Signal()
        cut_block = Signal()
        oversize = Signal()
        short = Signal()
        crc_bad = Signal()
        length_bad = Signal()
        verdict = checked.p.verdict
        with m.If(end):
            m.d.sync += [
                nonempty.eq(~verdict.empty),
                raw_oversize.eq(verdict.oversize),
                cut_block.eq(verdict.truncated),
                oversize.eq(count > MAX_PACKET - CRC_BYTES),
                short.eq(checked.p.short | (count < HEADER_BYTES)),
                crc_bad.eq(checked.p.bad_crc),
                length_bad.eq(header.length != count - HEADER_BYTES),
            ]
        good = Signal()
        reason = Signal(NakCode, init=NakCode.BAD_CRC)
        with m.If(raw_oversize):
            m.d.comb += reason.eq(NakCode.OVERSIZE)
        with m.Elif(cut_block):
            m.d.comb += reason.eq(NakCode.TRUNCATED)
        with m.Elif(oversize):
            m.d.comb += reason.eq(NakCode.OVERSIZE)
        with m.Elif(short):
            m.d.comb += reason.eq(NakCode.TRUNCATED)
        with m.Elif(crc_bad):
            m.d.comb += reason.eq(NakCode.BAD_CRC)
        with m.Elif(length_bad):
            m.d.comb += reason.eq(NakCode.BAD_LENGTH)
        with m.Else():
            m.d.comb += good.eq(1)
        return nonempty, good, reason
