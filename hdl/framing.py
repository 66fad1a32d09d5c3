"""Framed, checked packets over a byte stream: CRC-16, frame encoder and frame decoder.

The format is defined in :mod:`fliss.hdl.protocol` (and described in ``docs/protocol.md``): a
packet is header, payload and CRC-16; a frame is the packet COBS-encoded, then a zero byte.
:mod:`fliss.host.protocol` is the software model; the tests compare the two bit for bit.

COBS rather than SLIP: the overhead is bounded (one code byte per 254 bytes, plus one, plus the
delimiter) whatever the data, where SLIP doubles every escaped byte; raw event data is not
text, so SLIP's worst case would be the link's worst case. A zero byte only ever ends a frame,
so a receiver resynchronises at the next zero whatever came before.

Packets inside the gateware travel as :class:`PacketBeat` streams: a header beat (``first``),
then one beat per payload byte; ``last`` marks the final beat (the header beat itself when the
payload is empty).
"""

from amaranth.hdl import *
from amaranth.lib import crc as lib_crc, data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from .buffer import StreamBuffer
from .protocol import (DELIMITER, COBS_MAX_RUN, CRC_WIDTH, CRC_POLY, CRC_INIT, CRC_BYTES, Header,
                       HEADER_BYTES, MAX_PAYLOAD, MAX_PACKET, MAX_ENCODED, NakCode, COUNTER_BITS)


__all__ = ["PacketBeat", "crc16_next", "Crc16", "FrameEncoder", "FrameDecoder"]


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


#: The link's CRC-16/IBM-3740 as an :class:`amaranth.lib.crc.Algorithm`.
LINK_CRC = lib_crc.Algorithm(crc_width=CRC_WIDTH, polynomial=CRC_POLY, initial_crc=CRC_INIT,
                             reflect_input=False, reflect_output=False, xor_output=0)


def crc16_next(crc, byte):
    """CRC after one more byte: ``crc`` (16 bits) and ``byte`` (8 bits) are Amaranth values.

    The byte is processed most significant bit first with :data:`~fliss.hdl.protocol.CRC_POLY`,
    as CRC-16/IBM-3740 does; the result is a combinational expression.
    """
    crc = Value.cast(crc)
    byte = Value.cast(byte)
    for bit in reversed(range(8)):
        feedback = crc[CRC_WIDTH - 1] ^ byte[bit]
        shifted = Cat(C(0, 1), crc[:CRC_WIDTH - 1])
        crc = shifted ^ Mux(feedback, CRC_POLY, 0)
    return crc


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


def _byte(value, index):
    return Value.cast(value).word_select(index, 8)


class FrameEncoder(wiring.Component):
    """Frame encoder: packets in, framed bytes out.

    Adds the CRC, COBS-encodes header, payload and CRC and appends the delimiter; the output is
    exactly :func:`fliss.host.protocol.encode_frame` of the packet. The header is sent as given:
    the producer sets ``length`` to the number of payload beats and numbers the packets (one
    sequence counter for everything sent on the link). A beat other than a header beat where a
    packet should start is dropped and counted in ``stray_beats``.

    A run of non-zero bytes waits in the run buffer until the code byte in front of it is known.
    The buffer has two banks of :data:`~fliss.hdl.protocol.COBS_MAX_RUN` bytes: one run is sent
    from one bank while the next is collected, at one byte per cycle, in the other. Fed at one
    beat per cycle, the encoder only leaves a UART waiting when collecting a run takes longer
    than sending the block before it: at the start of a burst, or for a long run right after a
    short block (at most 254 cycles, less than 4 characters at 12 Mbaud from 80 MHz).

    Members
    -------
    i : In(stream.Signature(PacketBeat))
        Packets to send.
    o : Out(stream.Signature(8))
        Frame bytes, to a :class:`~fliss.hdl.uart.UartTx`.
    stray_beats : Out(32)
        Beats dropped because they came where a header beat should have (wraps around).
    """

    i:           In(stream.Signature(PacketBeat))
    o:           Out(stream.Signature(8))
    stray_beats: Out(COUNTER_BITS)

    def elaborate(self, platform):
        m = Module()

        m.submodules.crc = crc = LINK_CRC(8).create()
        m.submodules.run = run = Memory(shape=8, depth=2 << (COBS_MAX_RUN - 1).bit_length(),
                                        init=[])   # two banks
        run_wr = run.write_port()
        run_rd = run.read_port(transparent_for=())

        # Packet bytes, unencoded: header, payload, CRC (`s_*`), taken when `s_ready`. They reach
        # the COBS filler (`u_*`) through a half-rate register slice, tested for zero on the way
        # in, so that no path runs from the byte multiplexers here through the filler's decisions.
        m.submodules.byte_buffer = byte_buffer = StreamBuffer(
            data.StructLayout({"data": 8, "last": 1, "zero": 1}), full_rate=False)
        s_data = Signal(8)
        s_valid = Signal()
        s_last = Signal()
        s_ready = byte_buffer.i.ready
        m.d.comb += [
            byte_buffer.i.valid.eq(s_valid),
            byte_buffer.i.p.data.eq(s_data),
            byte_buffer.i.p.last.eq(s_last),
            byte_buffer.i.p.zero.eq(s_data == 0),
        ]
        u_data = byte_buffer.o.p.data
        u_valid = byte_buffer.o.valid
        u_last = byte_buffer.o.p.last
        u_ready = byte_buffer.o.ready
        header = Signal(Header)
        has_payload = Signal()
        index = Signal(range(HEADER_BYTES))
        s_checked = Signal()     # the byte is covered by the CRC
        m.d.comb += [
            crc.data.eq(s_data),
            crc.valid.eq(s_valid & s_ready & s_checked),
        ]
        crc_bytes = Array(_byte(crc.crc, k) for k in reversed(range(CRC_BYTES)))  # MSB first
        with m.FSM(name="source"):
            with m.State("IDLE"):
                m.d.comb += self.i.ready.eq(1)
                with m.If(self.i.valid & self.i.payload.first):
                    m.d.comb += crc.start.eq(1)
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
                    s_data.eq(_byte(header, index)),
                    s_valid.eq(1),
                    s_checked.eq(1),
                ]
                with m.If(s_ready):
                    m.d.sync += index.eq(index + 1)
                    with m.If(index == HEADER_BYTES - 1):
                        m.d.sync += index.eq(0)
                        with m.If(has_payload):
                            m.next = "PAYLOAD"
                        with m.Else():
                            m.next = "CRC"
            with m.State("PAYLOAD"):
                m.d.comb += [
                    s_data.eq(self.i.payload.data),
                    s_valid.eq(self.i.valid),
                    s_checked.eq(1),
                    self.i.ready.eq(s_ready),
                ]
                with m.If(self.i.valid & s_ready & self.i.payload.last):
                    m.next = "CRC"
            with m.State("CRC"):
                m.d.comb += [
                    s_data.eq(crc_bytes[index]),
                    s_valid.eq(1),
                    s_last.eq(index == CRC_BYTES - 1),
                ]
                with m.If(s_ready):
                    m.d.sync += index.eq(index + 1)
                    with m.If(s_last):
                        m.next = "IDLE"

        # COBS, filler: collect a run of non-zero bytes in one bank of the run buffer. A zero
        # byte, a full run or the end of the packet closes the block: its code byte, length and
        # bank go to `pending`, and the filler goes on in the other bank while the emitter sends
        # the block. The end of the packet closes the last run like a zero byte does (the run
        # after a final zero byte is empty: code 1), unless the packet ended with a full run,
        # as in `fliss.host.protocol.cobs_encode`.
        bank_bits = (COBS_MAX_RUN - 1).bit_length()
        run_len = Signal(range(COBS_MAX_RUN + 1))
        fill_bank = Signal()
        ending = Signal()           # the last packet byte is in, its final block is not closed
        pending = Signal()
        p_code = Signal(8)
        p_len = Signal(range(COBS_MAX_RUN + 1))
        p_bank = Signal()
        p_final = Signal()          # the block is the last of its frame
        emitting = Signal()
        e_bank = Signal()

        def close(code, length, final):
            m.d.sync += [
                pending.eq(1),
                p_code.eq(code),
                p_len.eq(length),
                p_bank.eq(fill_bank),
                p_final.eq(final),
                run_len.eq(0),
                fill_bank.eq(~fill_bank),
            ]

        m.d.comb += [
            run_wr.addr.eq(Cat(run_len[:bank_bits], fill_bank)),
            run_wr.data.eq(u_data),
        ]
        with m.If(ending):
            with m.If(~pending):
                close(run_len + 1, run_len, final=1)
                m.d.sync += ending.eq(0)
        with m.Else():
            m.d.comb += u_ready.eq(~pending & ~(emitting & (e_bank == fill_bank)))
            with m.If(u_valid & u_ready):
                with m.If(byte_buffer.o.p.zero):
                    close(run_len + 1, run_len, final=0)
                    m.d.sync += ending.eq(u_last)
                with m.Else():
                    m.d.comb += run_wr.en.eq(1)
                    with m.If(run_len == COBS_MAX_RUN - 1):
                        close(COBS_MAX_RUN + 1, COBS_MAX_RUN, final=u_last)
                    with m.Else():
                        m.d.sync += [
                            run_len.eq(run_len + 1),
                            ending.eq(u_last),
                        ]

        # COBS, emitter: the code byte, the run, and after the last block the delimiter
        e_code = Signal(8)
        e_len = Signal(range(COBS_MAX_RUN + 1))
        e_final = Signal()
        sent = Signal(range(COBS_MAX_RUN + 1))
        e_last = Signal()           # the byte of the run being sent is its last (registered)
        # The output byte is one LUT after the run buffer (block RAM, slow to output): which
        # byte goes out is decided a cycle ahead, into `e_is_code` and `e_is_data`, rather than
        # decoded from the state.
        e_is_code = Signal()
        e_is_data = Signal()
        m.d.comb += self.o.payload.eq(Mux(e_is_code, e_code, run_rd.data & e_is_data.replicate(8)))
        with m.FSM(name="emit"):
            with m.State("IDLE"):
                with m.If(pending):
                    m.d.sync += [
                        pending.eq(0),
                        emitting.eq(1),
                        e_code.eq(p_code),
                        e_len.eq(p_len),
                        e_bank.eq(p_bank),
                        e_final.eq(p_final),
                        e_is_code.eq(1),
                    ]
                    m.next = "CODE"
            with m.State("CODE"):
                m.d.comb += [
                    self.o.valid.eq(1),
                    run_rd.addr.eq(Cat(C(0, bank_bits), e_bank)),
                ]
                with m.If(self.o.ready):
                    m.d.sync += [sent.eq(0), e_is_code.eq(0), e_last.eq(e_len == 1)]
                    with m.If(e_len != 0):
                        m.d.sync += e_is_data.eq(1)
                        m.next = "DATA"
                    with m.Elif(e_final):
                        m.d.sync += emitting.eq(0)
                        m.next = "DELIMITER"
                    with m.Else():
                        m.d.sync += emitting.eq(0)
                        m.next = "IDLE"
            with m.State("DATA"):
                m.d.comb += [
                    self.o.valid.eq(1),
                    run_rd.addr.eq(Cat(Mux(self.o.ready, sent + 1, sent)[:bank_bits], e_bank)),
                ]
                with m.If(self.o.ready):
                    m.d.sync += [sent.eq(sent + 1), e_last.eq(sent + 2 == e_len)]
                    with m.If(e_last):
                        m.d.sync += [emitting.eq(0), e_is_data.eq(0)]
                        with m.If(e_final):
                            m.next = "DELIMITER"
                        with m.Else():
                            m.next = "IDLE"
            with m.State("DELIMITER"):
                assert DELIMITER == 0   # neither the code nor the data: zero
                m.d.comb += self.o.valid.eq(1)
                with m.If(self.o.ready):
                    m.next = "IDLE"

        return m


class FrameDecoder(wiring.Component):
    """Frame decoder: framed bytes in, verified packets out.

    Decodes COBS as bytes arrive, checks each frame at its delimiter and sends the packets that
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
    (header and two more); only then does ``i.ready`` fall until the packet has gone. From a
    UART at 12 Mbaud and 80 MHz (a byte every 67 cycles) that leaves over 400 cycles to read out
    a packet of at most 265 beats, so a consumer that takes a beat per cycle never stalls the
    input. The input also waits for one cycle after each delimiter, while the frame is judged.
    Every signal of ``o`` comes straight from a flip-flop.

    Members
    -------
    i : In(stream.Signature(8))
        Frame bytes, from a :class:`~fliss.hdl.uart.UartRx`.
    o : Out(stream.Signature(PacketBeat))
        Verified packets.
    drop : Out(1)
        Strobe: a frame was dropped.
    drop_reason : Out(NakCode)
        Why, valid with ``drop``: ``OVERSIZE``, ``TRUNCATED``, ``BAD_CRC`` or ``BAD_LENGTH``.
    packets : Out(32)
        Packets accepted (wraps around).
    bad_crc, truncated, oversize, bad_length : Out(32)
        Frames dropped for each reason (wrap around).
    tally : Out(data.StructLayout)
        One strobe per drop counter above, same names: high in each cycle it counts, for
        counters elsewhere.
    """

    i:           In(stream.Signature(8))
    o:           Out(stream.Signature(PacketBeat))
    drop:        Out(1)
    drop_reason: Out(NakCode, init=NakCode.BAD_CRC)
    packets:     Out(COUNTER_BITS)
    bad_crc:     Out(COUNTER_BITS)
    truncated:   Out(COUNTER_BITS)
    oversize:    Out(COUNTER_BITS)
    bad_length:  Out(COUNTER_BITS)
    tally:       Out(data.StructLayout({
                     "bad_crc": 1, "truncated": 1, "oversize": 1, "bad_length": 1}))

    def elaborate(self, platform):
        m = Module()

        m.submodules.crc = crc = LINK_CRC(8).create()
        m.submodules.buffer = buffer = Memory(shape=8, depth=MAX_PAYLOAD, init=[])
        buf_wr = buffer.write_port()
        buf_rd = buffer.read_port(transparent_for=())

        sending = Signal()      # a checked packet is on its way out
        min_packet = HEADER_BYTES + CRC_BYTES

        # Frame state
        raw_count = Signal(range(MAX_ENCODED + 2))  # bytes received, saturating
        dec_count = Signal(range(MAX_PACKET + 2))   # bytes decoded, saturating
        code_left = Signal(range(COBS_MAX_RUN + 1)) # bytes left in the current COBS block
        block_ff = Signal()                         # the current block has no implied zero
        header = Signal(Header)
        delay = Signal(8 * CRC_BYTES)               # the last CRC_BYTES decoded bytes

        # Input: stall when a payload byte would overwrite the packet being sent, and for the
        # cycle after each delimiter, while the frame is judged. (`early` is registered, for
        # timing, so it holds a cycle late: it ends a byte early, as a byte in that cycle may
        # decode to one more.)
        ending = Signal()
        early = Signal(init=1)
        m.d.sync += early.eq(dec_count < min_packet - 1)
        m.d.comb += self.i.ready.eq((~sending | early) & ~ending)
        take = Signal()
        delimiter = Signal()
        m.d.comb += [
            take.eq(self.i.valid & self.i.ready),
            delimiter.eq(self.i.payload == DELIMITER),
        ]

        # COBS decoding: at most one decoded byte per input byte
        d_valid = Signal()
        d_data = Signal(8)
        with m.If(take & ~delimiter):
            with m.If(raw_count <= MAX_ENCODED):
                m.d.sync += raw_count.eq(raw_count + 1)
            with m.If(code_left == 0):
                m.d.sync += [
                    code_left.eq(self.i.payload - 1),
                    block_ff.eq(self.i.payload == COBS_MAX_RUN + 1),
                ]
                m.d.comb += [
                    d_valid.eq((raw_count != 0) & ~block_ff),
                    d_data.eq(0),
                ]
            with m.Else():
                m.d.sync += code_left.eq(code_left - 1)
                m.d.comb += [
                    d_valid.eq(1),
                    d_data.eq(self.i.payload),
                ]

        # Decoded bytes: header, then a delay line of CRC_BYTES bytes, so that only payload
        # reaches the buffer, at offset `dec_count - HEADER_BYTES - CRC_BYTES`
        m.d.comb += [
            crc.valid.eq(d_valid),
            crc.data.eq(d_data),
            buf_wr.addr.eq(dec_count - min_packet),
            buf_wr.data.eq(delay[:8]),
        ]
        with m.If(d_valid):
            with m.If(dec_count <= MAX_PACKET):
                m.d.sync += dec_count.eq(dec_count + 1)
            with m.If(dec_count < HEADER_BYTES):
                m.d.sync += header.eq(Cat(header.as_value()[8:], d_data))
            with m.Else():
                m.d.sync += delay.eq(Cat(delay[8:], d_data))
                with m.If((dec_count >= min_packet) & (dec_count < MAX_PACKET)):
                    m.d.comb += buf_wr.en.eq(1)

        # Checks, in two steps for timing: at the delimiter each check is registered; in the next
        # cycle (`ending`, when the input waits) the verdict is drawn from them and registered
        # (`accept`, or `drop` with its reason), and the frame state is cleared. The counters
        # and the output follow from the verdict's registers.
        nonempty = Signal()
        raw_oversize = Signal()
        cut_block = Signal()
        oversize = Signal()
        short = Signal()
        crc_bad = Signal()
        length_bad = Signal()
        m.d.sync += ending.eq(take & delimiter)
        with m.If(take & delimiter):
            m.d.sync += [
                nonempty.eq(raw_count != 0),
                raw_oversize.eq(raw_count > MAX_ENCODED),
                cut_block.eq(code_left != 0),
                oversize.eq(dec_count > MAX_PACKET),
                short.eq(dec_count < min_packet),
                crc_bad.eq(crc.crc != 0),
                length_bad.eq(header.length != dec_count - min_packet),
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

        accept = Signal()
        sent_header = Signal(Header)    # the header of the accepted packet
        m.d.sync += [self.drop.eq(0), accept.eq(0)]
        with m.If(ending):
            m.d.comb += crc.start.eq(1)
            m.d.sync += [
                raw_count.eq(0),
                dec_count.eq(0),
                code_left.eq(0),
                block_ff.eq(0),
            ]
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
                for code, name in ((NakCode.OVERSIZE, "oversize"),
                                   (NakCode.TRUNCATED, "truncated"),
                                   (NakCode.BAD_CRC, "bad_crc"),
                                   (NakCode.BAD_LENGTH, "bad_length")):
                    counter = getattr(self, name)
                    with m.Case(code):
                        m.d.sync += counter.eq(counter + 1)
                        m.d.comb += getattr(self.tally, name).eq(1)

        # Output: a header beat, then the payload from the buffer; every output is a register.
        # `beat` counts beats sent. The buffer is read a beat ahead: `buf_rd.data` holds the
        # byte of the next beat, ready to be loaded into the output when this one is taken.
        start = Signal()
        beat = Signal(range(MAX_PAYLOAD + 1))
        advance = Signal()
        m.d.comb += [
            start.eq(accept),
            advance.eq(self.o.valid & self.o.ready),
            self.o.valid.eq(sending),
            buf_rd.addr.eq(Mux(start, 0, Mux(advance, beat + 1, beat))),
        ]
        with m.If(advance):
            m.d.sync += [
                beat.eq(beat + 1),
                self.o.payload.data.eq(buf_rd.data),
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
