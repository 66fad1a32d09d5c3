"""COBS encoding and decoding as stream stages.

Consistent Overhead Byte Stuffing removes every zero byte from a packet, so that a zero byte
(:data:`~fliss.hdl.protocol.DELIMITER`) only ever ends a frame: a block is a code byte ``n``,
then ``n - 1`` non-zero bytes, then an implied zero unless ``n`` is ``0xff`` (a full run of
:data:`~fliss.hdl.protocol.COBS_MAX_RUN` bytes) or the block ends the packet.
:func:`fliss.protocol.cobs_encode` and :func:`~fliss.protocol.cobs_decode` are the
software model; the tests compare the two bit for bit.

:class:`CobsEncoder` turns packets (:class:`PacketByte` streams) into frames, delimiter included;
:class:`CobsDecoder` turns frame bytes back into packet bytes and marks each delimiter with what
it found (:class:`DecodedByte`). Neither checks a CRC: :mod:`.crc` does, in the stage beside.
"""

from amaranth.hdl import C, Cat, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ..block_ram import byte_ram, check_registered_read, reads_registered
from .buffer import StreamBuffer
from ..protocol import DELIMITER, COBS_MAX_RUN


__all__ = ["PacketByte", "CobsVerdict", "DecodedByte", "CobsEncoder", "CobsDecoder"]


class PacketByte(data.Struct):
    """One byte of a packet; ``last`` is high on the packet's final byte."""
    data: 8
    last: 1


class CobsVerdict(data.Struct):
    """What :class:`CobsDecoder` found in a frame, given with its delimiter."""
    #: No byte came before the delimiter (two delimiters in a row).
    empty:     1
    #: The delimiter cut a COBS block short.
    truncated: 1
    #: More encoded bytes than the decoder's ``max_encoded``.
    oversize:  1


class DecodedByte(data.Struct):
    """One decoded byte (``end`` low), or the end of a frame (``end`` high, ``data`` zero) with
    the decoder's :class:`CobsVerdict` on it."""
    data:    8
    end:     1
    verdict: CobsVerdict


class CobsEncoder(wiring.Component):
    """COBS encoder: packets in, frames (encoded packet, then the delimiter) out.

    The output is exactly :func:`fliss.protocol.cobs_encode` of each packet followed by
    :data:`~fliss.hdl.protocol.DELIMITER`. An empty packet cannot be given (every packet has a
    ``last`` byte).

    A run of non-zero bytes waits in the run buffer until the code byte in front of it is known.
    The buffer has two banks of :data:`~fliss.hdl.protocol.COBS_MAX_RUN` bytes in block RAM: one
    run is sent from one bank while the next is collected, at one byte per cycle, in the other.
    The input goes through a half-rate register slice (so it takes at most a byte every two
    cycles), where each byte is tested for zero, so that no path runs from the producer through
    the filler's decisions. Each run byte is registered as it leaves the block RAM, so a run
    goes out at a byte every other cycle at most (as fast as the half-rate slice in front of
    the UART takes them); the output byte is one LUT after registers, its choice made a cycle
    ahead.
    The delimiter is the emitter's, not a stage of its own, which cost 13 logic cells on the
    iCE40UP5K (``docs/boards.md``).

    Parameters
    ----------
    registered_read : bool or None
        Read the run buffer through a :class:`~fliss.hdl.block_ram.RegisteredRam`, whose bytes
        leave the block RAM from its output register (for timing on an ECP5: the ULX3S at
        100 MHz), each addressed two cycles ahead; otherwise a plain memory read a cycle ahead
        (fewer logic cells: the iCEBreaker). The output is the same, cycle for cycle.
        ``None``: registered on an ECP5 platform (:func:`~fliss.hdl.block_ram.has_dp16kd`).

    Members
    -------
    i : In(stream.Signature(PacketByte))
        Packet bytes.
    o : Out(stream.Signature(8))
        Frame bytes.
    """

    i: In(stream.Signature(PacketByte))
    o: Out(stream.Signature(8))

    def __init__(self, *, registered_read=None):
        check_registered_read(registered_read)
        self.registered_read = registered_read
        super().__init__()

    def elaborate(self, platform):
        m = Module()

        # Run buffer: two banks of a run each
        registered = reads_registered(self.registered_read, platform)
        bank_bits = (COBS_MAX_RUN - 1).bit_length()
        run_wr, run_rd = byte_ram(m, "run", 2 << bank_bits, registered)
        m.d.comb += run_rd.en.eq(1)

        # Input slice, with the zero test on the way in
        m.submodules.byte_buffer = byte_buffer = StreamBuffer(
            data.StructLayout({"data": 8, "last": 1, "zero": 1}), full_rate=False)
        m.d.comb += [
            byte_buffer.i.valid.eq(self.i.valid),
            byte_buffer.i.p.data.eq(self.i.p.data),
            byte_buffer.i.p.last.eq(self.i.p.last),
            byte_buffer.i.p.zero.eq(self.i.p.data == 0),
            self.i.ready.eq(byte_buffer.i.ready),
        ]
        upstream = byte_buffer.o

        # Filler: collect a run of non-zero bytes in one bank of the run buffer. A zero byte, a
        # full run or the end of the packet closes the block: its code byte, length and bank go
        # to `pending`, and the filler goes on in the other bank while the emitter sends the
        # block. The end of the packet closes the last run like a zero byte does (the run after
        # a final zero byte is empty: code 1), unless the packet ended with a full run, as in
        # `fliss.protocol.cobs_encode`.
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
            run_wr.data.eq(upstream.p.data),
        ]
        with m.If(ending):
            with m.If(~pending):
                close(run_len + 1, run_len, final=1)
                m.d.sync += ending.eq(0)
        with m.Else():
            m.d.comb += upstream.ready.eq(~pending & ~(emitting & (e_bank == fill_bank)))
            with m.If(upstream.valid & upstream.ready):
                with m.If(upstream.p.zero):
                    close(run_len + 1, run_len, final=0)
                    m.d.sync += ending.eq(upstream.p.last)
                with m.Else():
                    m.d.comb += run_wr.en.eq(1)
                    with m.If(run_len == COBS_MAX_RUN - 1):
                        close(COBS_MAX_RUN + 1, COBS_MAX_RUN, final=upstream.p.last)
                    with m.Else():
                        m.d.sync += [
                            run_len.eq(run_len + 1),
                            ending.eq(upstream.p.last),
                        ]

        # Emitter: the code byte, the run, and after the last block the delimiter
        e_code = Signal(8)
        e_len = Signal(range(COBS_MAX_RUN + 1))
        e_final = Signal()
        sent = Signal(range(COBS_MAX_RUN + 1))
        e_last = Signal()           # the byte of the run being sent is its last (registered)
        # The run buffer is block RAM, slow to output, and may sit far from the UART: each run
        # byte is registered as it leaves it (LOAD, `e_data`), and the output byte is one LUT
        # after registers; which byte goes out is decided a cycle ahead, into `e_is_code` and
        # `e_is_data`, rather than decoded from the state. A plain read gives a byte a cycle
        # after its address (the run's first addressed in CODE, the next in DATA); a registered
        # read two cycles after (also in IDLE and LOAD, the cycles before those).
        e_data = Signal(8)
        e_is_code = Signal()
        e_is_data = Signal()
        m.d.comb += self.o.payload.eq(Mux(e_is_code, e_code, e_data & e_is_data.replicate(8)))
        with m.FSM(name="emit"):
            with m.State("IDLE"):
                if registered:
                    m.d.comb += run_rd.addr.eq(Cat(C(0, bank_bits), p_bank))
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
                        m.next = "LOAD"
                    with m.Elif(e_final):
                        m.d.sync += emitting.eq(0)
                        m.next = "DELIMITER"
                    with m.Else():
                        m.d.sync += emitting.eq(0)
                        m.next = "IDLE"
            with m.State("LOAD"):
                if registered:
                    m.d.comb += run_rd.addr.eq(Cat((sent + 1)[:bank_bits], e_bank))
                m.d.sync += e_data.eq(run_rd.data)
                m.next = "DATA"
            with m.State("DATA"):
                m.d.comb += [
                    self.o.valid.eq(1),
                    run_rd.addr.eq(Cat((sent + 1)[:bank_bits], e_bank)),
                ]
                with m.If(self.o.ready):
                    m.d.sync += [sent.eq(sent + 1), e_last.eq(sent + 2 == e_len)]
                    with m.If(e_last):
                        m.d.sync += [emitting.eq(0), e_is_data.eq(0)]
                        with m.If(e_final):
                            m.next = "DELIMITER"
                        with m.Else():
                            m.next = "IDLE"
                    with m.Else():
                        m.next = "LOAD"
            with m.State("DELIMITER"):
                assert DELIMITER == 0   # neither the code nor the data: zero
                m.d.comb += self.o.valid.eq(1)
                with m.If(self.o.ready):
                    m.next = "IDLE"

        return m


class CobsDecoder(wiring.Component):
    """COBS decoder: frame bytes in, decoded bytes and frame ends out.

    Cut-through, with no latency: each input byte is taken in the cycle ``o`` takes what it
    decodes to (``i.ready`` is ``o.ready``). A code byte decodes to the zero implied by the block
    before it (none for the first block of a frame, or after a full block); a data byte to
    itself; a delimiter to an ``end`` beat carrying the :class:`CobsVerdict` of the frame, after
    which the decoder starts a new frame. It never wedges, whatever the input.

    Parameters
    ----------
    max_encoded : int
        Longest frame, delimiter excluded, in bytes; a longer one is ``oversize``.

    Members
    -------
    i : In(stream.Signature(8))
        Frame bytes.
    o : Out(stream.Signature(DecodedByte))
        Decoded bytes and frame ends.
    """

    i: In(stream.Signature(8))
    o: Out(stream.Signature(DecodedByte))

    def __init__(self, max_encoded):
        if not isinstance(max_encoded, int) or max_encoded < 1:
            raise ValueError(f"Longest frame must be a positive integer, not {max_encoded!r}")
        self.max_encoded = max_encoded
        super().__init__()

    def elaborate(self, platform):
        m = Module()

        count = Signal(range(self.max_encoded + 2))     # bytes of the frame, saturating
        code_left = Signal(range(COBS_MAX_RUN + 1))     # bytes left in the current block
        at_code = Signal(init=1)                        # `code_left == 0`, as a register
        block_ff = Signal()                             # the current block has no implied zero

        take = Signal()
        delimiter = Signal()
        m.d.comb += [
            self.i.ready.eq(self.o.ready),
            take.eq(self.i.valid & self.i.ready),
            delimiter.eq(self.i.payload == DELIMITER),
        ]

        with m.If(delimiter):
            m.d.comb += [
                self.o.valid.eq(self.i.valid),
                self.o.p.end.eq(1),
                self.o.p.verdict.empty.eq(count == 0),
                self.o.p.verdict.truncated.eq(~at_code),
                self.o.p.verdict.oversize.eq(count > self.max_encoded),
            ]
            with m.If(take):
                m.d.sync += [count.eq(0), code_left.eq(0), at_code.eq(1), block_ff.eq(0)]
        with m.Elif(at_code):
            # Code byte: the zero implied by the block before
            m.d.comb += self.o.valid.eq(self.i.valid & (count != 0) & ~block_ff)
            with m.If(take):
                m.d.sync += [
                    code_left.eq(self.i.payload - 1),
                    at_code.eq(self.i.payload == 1),
                    block_ff.eq(self.i.payload == COBS_MAX_RUN + 1),
                ]
        with m.Else():
            m.d.comb += [
                self.o.valid.eq(self.i.valid),
                self.o.p.data.eq(self.i.payload),
            ]
            with m.If(take):
                m.d.sync += [code_left.eq(code_left - 1), at_code.eq(code_left == 1)]
        with m.If(take & ~delimiter & (count <= self.max_encoded)):
            m.d.sync += count.eq(count + 1)

        return m
