"""Formal harnesses of the link: the UART receiver (``hdl/uart.py``), the frame decoder
(``hdl/framing.py`` with ``hdl/cobs.py`` and ``hdl/crc.py``) and the command processor with its
register file (``hdl/command.py``, ``hdl/regfile.py``).

The UART runs at four cycles a bit (the shortest :func:`fliss.hdl.uart.bit_cycles` allows), so
that a character lasts 40 cycles. Inputs are free in every cycle (any line, any byte, any
backpressure). Mutants override a block's own statements (:func:`._harness.open_block`).
"""

from amaranth.hdl import Assert, Assume, Cover, Module, ResetSignal, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In

from fliss.hdl.crc import CRC_INIT, crc16_next
from fliss.hdl.framing import FrameDecoder
from fliss.hdl.protocol import CRC_BYTES, DELIMITER, HEADER_BYTES, MAX_PACKET, NakCode
from fliss.hdl.uart import CHARACTER_BITS, FRACTION_BITS, UartRx

from ._harness import assigned, open_block, open_submodule, past
from .runner import Proof


# UART receiver

#: Clock and baud rate of the UART harness: four cycles a bit.
UART_CLOCK_HZ, UART_BAUD = 4_000_000, 1_000_000

#: The receiver is idle (looking for a start bit) after this many cycles of a high line.
UART_IDLE_CYCLES = 39


def _uart_break_stuck(block, module):
    # a framing error's wait for the line to go high never ends
    state, = assigned(module, "fsm_state")
    with module.If(state == 2):
        module.d.sync += state.eq(2)


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
        dut = UartRx(clock_hz=UART_CLOCK_HZ, baud=UART_BAUD)
        dut._MustUse__silence = True      # (elaborated here, not by the converter)
        dut._MustUse__silence = True      # (elaborated here, not by the converter)
        m.submodules.dut = module = open_block(dut, self.mutate, platform)
        m.d.comb += [dut.rx.eq(self.rx), dut.o.ready.eq(self.ready),
                     Assume(~ResetSignal("sync"))]

        # consecutive cycles of a high line before this one, saturating
        high = Signal(range(UART_IDLE_CYCLES + 1))
        with m.If(~self.rx):
            m.d.sync += high.eq(0)
        with m.Elif(high != UART_IDLE_CYCLES):
            m.d.sync += high.eq(high + 1)

        state, cycle, edge, target, bit = assigned(module, "fsm_state", "cycle", "edge",
                                                  "target", "bit")
        idle, receive, wait_high = state == 0, state == 1, state == 2
        step = dut.bit_cycles
        m.d.comb += Assert((high != UART_IDLE_CYCLES) | idle)

        # Invariants of the receiver's timing (for the induction)
        m.d.comb += Assert(idle | receive | wait_high)
        with m.If(receive):
            m.d.comb += [
                Assert(bit < CHARACTER_BITS),
                Assert(edge == step // 2 + bit * step),
                Assert(target == (edge >> FRACTION_BITS) + 1),
                Assert((cycle >= 1) & (cycle <= target)),
                Assert(high <= cycle + 1),
                Assert((bit == 0) | (high + 1 <= cycle)),
            ]
        with m.If(wait_high):
            m.d.comb += Assert(high <= 4)

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
    """The frame decoder on free bytes and backpressure: two cycles after it takes a delimiter,
    every part of it is at the start of a frame (COBS block and count, CRC and its delay line,
    the frame's byte count), and a cycle later it takes input again (unless that cycle judges
    another frame): whatever came before, it resynchronises at the next delimiter."""

    valid:   In(1)
    payload: In(8)
    ready:   In(1)

    def __init__(self, cobs_mutate=None):
        self.cobs_mutate = cobs_mutate
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        dut = FrameDecoder()
        dut._MustUse__silence = True
        m.submodules.dut = module = open_block(dut, platform=platform)
        _, cobs = open_submodule(module, "cobs", self.cobs_mutate, platform)
        crc_block, crc = open_submodule(module, "crc", platform=platform)
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

        delimiter = Signal()
        m.d.comb += delimiter.eq(dut.i.valid & dut.i.ready & (dut.i.payload == DELIMITER))
        fresh = Signal()
        m.d.comb += fresh.eq((count == 0) & (cobs_count == 0) & (code_left == 0) & at_code &
                             ~block_ff & (held == 0) & (engine.crc == CRC_INIT))
        m.d.comb += [
            Assert(~past(m, delimiter, 2) | fresh),
            Assert(~past(m, delimiter, 3) | dut.i.ready | ending),
        ]
        # Invariant (for the induction): the COBS block's register `at_code` is `code_left == 0`
        m.d.comb += Assert(at_code == (code_left == 0))

        # A frame cut short in a COBS block, then a good packet after the delimiter
        cut = Signal()
        with m.If(delimiter & ~at_code & (cobs_count != 0)):
            m.d.sync += cut.eq(1)
        m.d.comb += [
            Cover(past(m, delimiter, 2) & fresh & cut),
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
        dut = FrameDecoder()
        dut._MustUse__silence = True
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
        m.d.comb += [Assert(engine.crc == crc), Assert(size <= limit)]
        ending, = assigned(module, "ending")
        with m.If(ending):      # (the frame's byte count is cleared at the end of this cycle)
            m.d.comb += [Assert(size == 0), Assert(held == 0)]
        with m.Elif(size < CRC_BYTES):
            m.d.comb += [Assert(held == size), Assert(count == 0)]
        with m.Else():
            m.d.comb += Assert(held == CRC_BYTES)
            with m.If(size < limit):
                m.d.comb += Assert(count == size - CRC_BYTES)
            with m.Else():
                m.d.comb += Assert(count == limit - CRC_BYTES)
        # (the header register, as bits, and the CRC checker's delay line: bytes 2 and 3)
        delay, = assigned(crc_module, "delay")
        with m.If(~ending & (count >= HEADER_BYTES)):
            m.d.comb += Assert(header[16:] == length)
        with m.If(~ending & (count == HEADER_BYTES - 1)):
            m.d.comb += Assert(header[24:] == length[:8])
        with m.If(size == 3):
            m.d.comb += Assert(delay[8:] == length[:8])
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


PROOFS = [
    Proof("link.uart_rx_idle", UartRxHarness, "prove", 4,
          f"UART receiver: idle (ready for a start bit) after {UART_IDLE_CYCLES} cycles of a "
          f"high line, from any state",
          mutant=lambda: UartRxHarness(_uart_break_stuck), cover_depth=60, mutant_depth=70),
    Proof("link.decoder_resync", DecoderHarness, "prove", 4,
          "frame decoder: from any state, at the start of a frame two cycles after a delimiter "
          "and taking input a cycle later",
          mutant=lambda: DecoderHarness(_cobs_keeps_block), cover_depth=20, mutant_depth=10),
    Proof("link.decoder_checks", DecoderChecksHarness, "prove", 3,
          "frame decoder: a packet is accepted only from a frame with a good CRC and length",
          mutant=lambda: DecoderChecksHarness(_crc_unchecked), cover_depth=16, mutant_depth=12),
]
