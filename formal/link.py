"""Formal harnesses of the link: the UART receiver (``hdl/link/uart.py``), the frame decoder
(``hdl/link/framing.py`` with ``hdl/link/cobs.py`` and ``hdl/link/crc.py``) and the command processor with its
register file (``hdl/link/command.py``, ``hdl/regfile.py``).

The UART runs at four cycles a bit (the shortest :func:`fliss.hdl.clock.bit_cycles` allows), so
that a character lasts 40 cycles. Inputs are free in every cycle (any line, any byte, any
backpressure). Mutants override a block's own statements (:func:`._harness.open_block`).
"""

from amaranth.hdl import Assert, Assume, Cover, Module, ResetSignal, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In

from ..hdl.link.command import CommandProcessor
from ..hdl.link.crc import CRC_INIT, crc16_next
from ..hdl.link.framing import FrameDecoder, PacketBeat
from ..hdl.protocol import (CRC_BYTES, DELIMITER, HEADER_BYTES, MAX_PACKET, MAX_PAYLOAD, NakCode,
                            PacketType)
from ..hdl.link.uart import CHARACTER_BITS, UartRx
from ..hdl.clock import FRACTION_BITS

from ._harness import assigned, fsm, open_block, open_submodule, past
from .runner import Proof


def _invariant(mutate):
    """``Assert`` for the invariants that help an induction; nothing for a mutant, whose
    counterexample must break the property itself."""
    return Assert if mutate is None else (lambda *args, **kwargs: [])


# UART receiver

#: Clock and baud rate of the UART harness: four cycles a bit.
UART_CLOCK_HZ, UART_BAUD = 4_000_000, 1_000_000

#: The receiver is idle (looking for a start bit) after this many cycles of a high line.
UART_IDLE_CYCLES = 39


def _uart_break_stuck(block, module):
    # a framing error's wait for the line to go high never ends
    state, is_state = fsm(module)
    with module.If(is_state("BREAK")):
        module.d.sync += state.eq(state)


class UartRxHarness(wiring.Component):
    """The UART receiver on a free line: after :data:`UART_IDLE_CYCLES` cycles of a high line
    it is idle, ready for the next start bit, whatever came before (a break, noise, a
    character cut short)."""

    rx:    In(1)
    ready: In(1)

    def __init__(self, mutate=None):
        self.mutate = mutate
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        inv = _invariant(self.mutate)
        dut = UartRx(clock_hz=UART_CLOCK_HZ, baud=UART_BAUD)
        m.submodules.dut = module = open_block(dut, self.mutate, platform)
        m.d.comb += [dut.rx.eq(self.rx), dut.o.ready.eq(self.ready),
                     Assume(~ResetSignal("sync"))]

        # consecutive cycles of a high line before this one, saturating
        high = Signal(range(UART_IDLE_CYCLES + 1))
        with m.If(~self.rx):
            m.d.sync += high.eq(0)
        with m.Elif(high != UART_IDLE_CYCLES):
            m.d.sync += high.eq(high + 1)

        state, is_state = fsm(module)
        cycle, edge, target, bit = assigned(module, "cycle", "edge", "target", "bit")
        idle, receive, wait_high = is_state("IDLE"), is_state("RECEIVE"), is_state("BREAK")
        step = dut.bit_cycles
        m.d.comb += Assert((high != UART_IDLE_CYCLES) | idle)

        # Invariants of the receiver's timing (for the induction)
        m.d.comb += inv(idle | receive | wait_high)
        with m.If(receive):
            m.d.comb += [
                inv(bit < CHARACTER_BITS),
                inv(edge == step // 2 + bit * step),
                inv(target == (edge >> FRACTION_BITS) + 1),
                inv((cycle >= 1) & (cycle <= target)),
                inv(high <= cycle + 1),
                inv((bit == 0) | (high + 1 <= cycle)),
            ]
        with m.If(wait_high):
            m.d.comb += inv(high <= 4)

        m.d.comb += [
            Cover(dut.o.valid & (high == 4)),                    # a byte, then the line idles
            Cover(past(m, dut.framing_error, 8) & idle & (high == 8)),   # a break, then idle
            Cover(receive & (high == UART_IDLE_CYCLES - 1)),      # the bound is tight
        ]
        return m


# Frame decoder

def _cobs_keeps_block(block, module):
    # a delimiter does not end the COBS block it cuts short
    delimiter, code_left, at_code = assigned(module, "delimiter", "code_left", "at_code")
    with module.If(delimiter):
        module.d.sync += [code_left.eq(code_left), at_code.eq(at_code)]


class DecoderHarness(wiring.Component):
    """The frame decoder on free bytes and backpressure, with the input resting for the
    three cycles after a delimiter (a UART gives a byte at most every ten bit times, at least
    40 cycles): three cycles after it takes a delimiter while no packet goes out (a delimiter
    taken behind a stalled register slice waits there), every part of it is at the start of a
    frame (COBS block and count, the register slice between COBS and CRC, CRC and its delay
    line, the frame's byte count), and a cycle later it takes input again (unless that cycle
    judges another frame): whatever came before, it resynchronises at the next delimiter."""

    valid:   In(1)
    payload: In(8)
    ready:   In(1)

    def __init__(self, cobs_mutate=None):
        self.mutate = cobs_mutate
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        inv = _invariant(self.mutate)
        dut = FrameDecoder()
        m.submodules.dut = module = open_block(dut, platform=platform)
        _, cobs = open_submodule(module, "cobs", self.mutate, platform)
        crc_block, crc = open_submodule(module, "crc", platform=platform)
        decoded, slice_module = open_submodule(module, "decoded", platform=platform)
        skid_valid, = assigned(slice_module, "skid_valid")
        m.d.comb += [
            dut.i.valid.eq(self.valid), dut.i.payload.eq(self.payload),
            dut.o.ready.eq(self.ready),
            Assume(~ResetSignal("sync")),
        ]
        count, ending = assigned(module, "count", "ending")
        cobs_count, code_left, at_code, block_ff = assigned(cobs, "count", "code_left",
                                                            "at_code", "block_ff")
        held, = assigned(crc, "held")
        engine = crc._named_submodules["engine"][0]

        # A delimiter taken while no packet goes out and the register slice is empty (taken
        # behind a stalled slice, it waits there for the packet to go)
        sending, = assigned(module, "sending")
        delimiter = Signal()
        m.d.comb += delimiter.eq(dut.i.valid & dut.i.ready & (dut.i.payload == DELIMITER) &
                                 ~sending & ~decoded.o.valid)
        resting = Signal()      # within three cycles after a delimiter
        m.d.comb += [
            resting.eq(past(m, delimiter, 1) | past(m, delimiter, 2) | past(m, delimiter, 3)),
            Assume(~resting | ~self.valid),
        ]
        fresh = Signal()
        m.d.comb += fresh.eq((count == 0) & (cobs_count == 0) & (code_left == 0) & at_code &
                             ~block_ff & ~decoded.o.valid & (held == 0) &
                             (engine.crc == CRC_INIT))
        m.d.comb += [
            Assert(~past(m, delimiter, 3) | fresh),
            Assert(~past(m, delimiter, 4) | dut.i.ready | ending),
        ]
        # Invariants (for the induction): the COBS block's register `at_code` is
        # `code_left == 0`; the register slice holds a second beat only behind a first
        m.d.comb += [inv(at_code == (code_left == 0)), inv(~skid_valid | decoded.o.valid)]

        # A frame cut short in a COBS block, then a good packet after the delimiter
        cut = Signal()
        with m.If(delimiter & ~at_code & (cobs_count != 0)):
            m.d.sync += cut.eq(1)
        m.d.comb += [
            Cover(past(m, delimiter, 3) & fresh & cut),
            Cover(dut.o.valid & dut.o.p.first & cut),
        ]
        return m


def _crc_unchecked(block, module):
    # the CRC check skipped
    end, crc_bad = assigned(module, "end", "crc_bad")
    with module.If(end):
        module.d.sync += crc_bad.eq(0)


class DecoderChecksHarness(wiring.Component):
    """The frame decoder on free bytes and backpressure: a packet is accepted (and sent to the
    command processor) only from a frame whose CRC is right and whose header ``length`` is the
    number of its payload bytes, both computed here from the decoded bytes of the frame."""

    valid:   In(1)
    payload: In(8)
    ready:   In(1)

    def __init__(self, mutate=None):
        self.mutate = mutate
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        inv = _invariant(self.mutate)
        dut = FrameDecoder()
        m.submodules.dut = module = open_block(dut, self.mutate, platform)
        _, cobs = open_submodule(module, "cobs", platform=platform)
        crc_block, crc_module = open_submodule(module, "crc", platform=platform)
        m.d.comb += [
            dut.i.valid.eq(self.valid), dut.i.payload.eq(self.payload),
            dut.o.ready.eq(self.ready),
            Assume(~ResetSignal("sync")),
        ]

        # The frame's decoded bytes (CRC included), as the COBS decoder gives them
        beat = crc_block.i
        taken = Signal()
        m.d.comb += taken.eq(beat.valid & beat.ready)
        limit = MAX_PACKET + 1
        size = Signal(range(limit + 1))          # bytes, saturating
        crc = Signal(16, init=CRC_INIT)
        length = Signal(16)                      # header `length`, from bytes 2 and 3
        with m.If(taken & beat.p.end):
            m.d.sync += [size.eq(0), crc.eq(CRC_INIT)]
        with m.Elif(taken):
            m.d.sync += crc.eq(crc16_next(crc, beat.p.data))
            with m.If(size != limit):
                m.d.sync += size.eq(size + 1)
            with m.If(size == 2):
                m.d.sync += length[:8].eq(beat.p.data)
            with m.If(size == 3):
                m.d.sync += length[8:].eq(beat.p.data)
        good = Signal()
        m.d.comb += good.eq((size >= HEADER_BYTES + CRC_BYTES) & (crc == 0) &
                            (length == size - HEADER_BYTES - CRC_BYTES))
        judged_good = past(m, taken & beat.p.end & good, 2)
        accept, = assigned(module, "accept")
        m.d.comb += Assert(~accept | judged_good)

        # Invariants (for the induction): the decoder's CRC, byte count and header are these
        count, header = assigned(module, "count", "header")
        held, = assigned(crc_module, "held")
        engine = crc_module._named_submodules["engine"][0]
        m.d.comb += [inv(engine.crc == crc), inv(size <= limit)]
        ending, = assigned(module, "ending")
        with m.If(ending):      # (the frame's byte count is cleared at the end of this cycle)
            m.d.comb += [inv(size == 0), inv(held == 0)]
        with m.Elif(size < CRC_BYTES):
            m.d.comb += [inv(held == size), inv(count == 0)]
        with m.Else():
            m.d.comb += inv(held == CRC_BYTES)
            with m.If(size < limit):
                m.d.comb += inv(count == size - CRC_BYTES)
            with m.Else():
                m.d.comb += inv(count == limit - CRC_BYTES)
        # (the header register, as bits, and the CRC checker's delay line: bytes 2 and 3)
        delay, = assigned(crc_module, "delay")
        with m.If(~ending & (count >= HEADER_BYTES)):
            m.d.comb += inv(header[16:] == length)
        with m.If(~ending & (count == HEADER_BYTES - 1)):
            m.d.comb += inv(header[24:] == length[:8])
        with m.If(size == 3):
            m.d.comb += inv(delay[8:] == length[:8])
        with m.If(size == 4):
            m.d.comb += Assert(delay == length)
        with m.If(size == 5):
            m.d.comb += Assert(delay[:8] == length[8:])

        m.d.comb += [
            Cover(accept & (past(m, length, 3) == 1)),           # a packet with a payload byte
            Cover(dut.drop & (dut.drop_reason == NakCode.BAD_CRC)),
            Cover(dut.drop & (dut.drop_reason == NakCode.BAD_LENGTH)),
        ]
        return m


# Command processor and register file

#: A command is answered (its reply's header leaves) within this many cycles of its last beat,
#: when nothing waits on the reply stream or the STATUS counters.
ANSWER_CYCLES = 6


def _answers_twice(block, module):
    # a reply is sent again once it has gone
    state, is_state = fsm(module)
    index, reply_final = assigned(module, "index", "reply_final")
    replies = module._named_submodules["reply_buffer"][0].i
    with module.If(is_state("DATA") & replies.ready & (index == reply_final)):
        module.d.sync += state.eq(module._generated["fsm"].encoding["HEADER"])


def _refusal_unanswered(block, module):
    # a refused command is never answered
    state, is_state = fsm(module)
    refusal, = assigned(module, "refusal")
    with module.If(is_state("DISPATCH") & refusal):
        module.d.sync += state.eq(module._generated["fsm"].encoding["DISPATCH"])


def _commits_unchecked(block, module):
    # a WRITE's values are committed as they come in, before the packet is whole
    check, = assigned(module, "check")
    module.d.comb += block.registers.commit.eq(check)


class CommandHarness(wiring.Component):
    """The command processor and its register file, fed any sequence of well-formed packets
    (as the frame decoder sends them: a header beat, then ``length`` payload beats) and link
    errors, with any backpressure on its replies.

    ``check`` is ``"answer"``: a command is taken only when none is waiting for its reply, and
    every reply answers exactly one command or a link error (``patient``: and a command is
    answered within :data:`ANSWER_CYCLES` cycles); or ``"write"``: the settings change only in
    the cycle after a commit, and only the commit of a whole ``WRITE`` packet taken from the
    decoder (with a decoder that accepts only good frames, ``link.decoder_checks``, no bad frame
    ever changes a register).
    """

    packets:       In(stream.Signature(PacketBeat))
    replies_ready: In(1)
    link_error:    In(1)
    status_ready:  In(1)

    def __init__(self, check, *, patient=False, mutate=None):
        self.check, self.patient, self.mutate = check, patient, mutate
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        inv = _invariant(self.mutate)
        dut = CommandProcessor(clock_hz=UART_CLOCK_HZ, baud=UART_BAUD)
        m.submodules.dut = module = open_block(dut, self.mutate, platform)
        m.d.comb += [
            dut.packets.valid.eq(self.packets.valid), dut.packets.payload.eq(self.packets.payload),
            self.packets.ready.eq(dut.packets.ready),
            dut.replies.ready.eq(self.replies_ready),
            dut.link_error.eq(self.link_error),
            dut.status.ready.eq(self.status_ready),
            Assume(~ResetSignal("sync")),
        ]
        if self.patient:
            m.d.comb += [Assume(self.replies_ready), Assume(self.status_ready)]

        # Well-formed packets, held until taken
        beat = self.packets
        taken = Signal()
        m.d.comb += taken.eq(beat.valid & beat.ready)
        inside = Signal()                       # between a header beat and the last beat
        left = Signal(range(MAX_PAYLOAD + 1))   # payload beats to come
        header = Signal.like(beat.p.header)
        with m.If(beat.valid):
            with m.If(~inside):
                m.d.comb += [Assume(beat.p.first), Assume(beat.p.header.length <= MAX_PAYLOAD),
                             Assume(beat.p.last == (beat.p.header.length == 0))]
            with m.Else():
                m.d.comb += [Assume(~beat.p.first), Assume(beat.p.header == header),
                             Assume(beat.p.last == (left == 1))]
        with m.If(past(m, beat.valid & ~beat.ready)):
            m.d.comb += [Assume(beat.valid), Assume(beat.payload == past(m, beat.payload))]
        with m.If(taken & beat.p.first):
            m.d.sync += [inside.eq(~beat.p.last), left.eq(beat.p.header.length),
                         header.eq(beat.p.header)]
        with m.Elif(taken):
            m.d.sync += [inside.eq(~beat.p.last), left.eq(left - 1)]
        m.d.comb += inv(~inside | (left != 0))

        # Commands and replies
        state, is_state = fsm(module)
        link_pending, = assigned(module, "link_pending")
        replies = module._named_submodules["reply_buffer"][0].i
        reply_start = Signal()
        m.d.comb += reply_start.eq(replies.valid & replies.ready & replies.p.first)
        command = Signal()
        m.d.comb += command.eq(taken & beat.p.first)
        owed = Signal()                         # a command waits for its reply
        whole = Signal()                        # ... and its packet has been taken whole
        link_nak = Signal()                     # a link error's NAK is on its way
        is_write = Signal()
        wait = Signal(range(ANSWER_CYCLES + 1))
        with m.If(command):
            m.d.sync += [owed.eq(1), whole.eq(beat.p.last), wait.eq(0),
                         is_write.eq(beat.p.header.type == PacketType.WRITE)]
        with m.Elif(reply_start & owed):
            m.d.sync += [owed.eq(0), whole.eq(0), wait.eq(0)]
        with m.Elif(taken & beat.p.last):
            m.d.sync += whole.eq(1)
        with m.Elif(owed & whole & (wait != ANSWER_CYCLES)):
            m.d.sync += wait.eq(wait + 1)
        with m.If(is_state("IDLE") & ~command & link_pending):
            m.d.sync += link_nak.eq(1)
        with m.Elif(reply_start & ~owed):
            m.d.sync += link_nak.eq(0)

        commit = dut.registers.commit
        settings = dut.registers.settings.as_value()
        if self.check == "answer":
            m.d.comb += [
                Assert(~command | ~owed),                   # one command at a time
                Assert(~reply_start | owed | link_nak),     # no reply unless one is owed
            ]
            if self.patient:
                m.d.comb += Assert(wait != ANSWER_CYCLES)
                # (invariants: how long each step takes)
                for states, most in ((("CHECK",), 0), (("VERDICT",), 1), (("DISPATCH",), 2),
                                     (("CONSISTENCY", "SNAPSHOT"), 3), (("COMMIT",), 4)):
                    m.d.comb += inv(~is_state(*states) | (wait <= most))
                with m.If(is_state("HEADER") & owed):
                    m.d.comb += inv((wait <= 5) | ((wait <= 6) & ~dut.replies.valid))
            m.d.comb += [
                Cover(reply_start & owed & is_state("HEADER") &
                      (past(m, state) == module._generated["fsm"].encoding["COMMIT"])),
                Cover(reply_start & ~owed),                 # a link error's NAK
                Cover(reply_start & owed & (wait == ANSWER_CYCLES - 1)),    # the bound is tight
            ]
        else:
            m.d.comb += [
                Assert(~commit | (owed & whole & is_write)),
                Assert((settings == past(m, settings)) | past(m, commit)),
                Cover(settings != past(m, settings)),
            ]

        # Invariants (for the induction)
        accepting, cmd_type = assigned(module, "accepting", "cmd_type")
        m.d.comb += [
            inv(state < len(module._generated["fsm"].encoding)),
            inv(~owed | (is_write == (cmd_type == PacketType.WRITE))),
            inv(accepting == is_state("IDLE", "PAYLOAD")),
            inv(is_state("IDLE", "DATA") | owed | (is_state("HEADER") & link_nak)),
            inv(~is_state("IDLE", "DATA") | ~owed),
            inv(~link_nak | is_state("HEADER")),
            inv(~(owed & link_nak)),
            inv((owed & whole) | (wait == 0)),
            inv(wait <= ANSWER_CYCLES),
            inv(~owed | inside | whole),
            inv(~is_state("PAYLOAD") | (inside & ~whole)),
            inv(~is_state("IDLE") | ~inside),
            inv(~inside | is_state("PAYLOAD")),
        ]
        return m


PROOFS = [
    Proof("link.uart_rx_idle", UartRxHarness, "prove", 4,
          f"UART receiver: idle (ready for a start bit) after {UART_IDLE_CYCLES} cycles of a "
          f"high line, from any state",
          mutant=lambda: UartRxHarness(_uart_break_stuck), cover_depth=60, mutant_depth=90),
    Proof("link.decoder_resync", DecoderHarness, "prove", 8,
          "frame decoder: from any state, at the start of a frame three cycles after a "
          "delimiter taken while no packet goes out (the input resting) and taking input a "
          "cycle later",
          mutant=lambda: DecoderHarness(_cobs_keeps_block), cover_depth=20, mutant_depth=10),
    Proof("link.decoder_checks", DecoderChecksHarness, "prove", 3,
          "frame decoder: a packet is accepted only from a frame with a good CRC and length",
          mutant=lambda: DecoderChecksHarness(_crc_unchecked), cover_depth=16, mutant_depth=12),
    Proof("link.command_one_reply", lambda: CommandHarness("answer"), "prove", 4,
          "command processor: one command at a time, and every reply answers exactly one "
          "command or a link error",
          mutant=lambda: CommandHarness("answer", mutate=_answers_twice), cover_depth=16,
          mutant_depth=12),
    Proof("link.command_answers", lambda: CommandHarness("answer", patient=True), "prove", 4,
          f"command processor: every command answered within {ANSWER_CYCLES} cycles of its "
          f"last beat when replies are taken",
          mutant=lambda: CommandHarness("answer", patient=True, mutate=_refusal_unanswered),
          cover_depth=16, mutant_depth=16),
    Proof("link.command_writes", lambda: CommandHarness("write"), "prove", 4,
          "register file: settings change only by the commit of a whole WRITE packet",
          mutant=lambda: CommandHarness("write", mutate=_commits_unchecked), cover_depth=20,
          mutant_depth=16),
]
