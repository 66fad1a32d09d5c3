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

from fliss.hdl.crc import CRC_INIT
from fliss.hdl.framing import FrameDecoder
from fliss.hdl.protocol import DELIMITER
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


PROOFS = [
    Proof("link.uart_rx_idle", UartRxHarness, "prove", 4,
          f"UART receiver: idle (ready for a start bit) after {UART_IDLE_CYCLES} cycles of a "
          f"high line, from any state",
          mutant=lambda: UartRxHarness(_uart_break_stuck), cover_depth=60, mutant_depth=70),
    Proof("link.decoder_resync", DecoderHarness, "prove", 4,
          "frame decoder: from any state, at the start of a frame two cycles after a delimiter "
          "and taking input a cycle later",
          mutant=lambda: DecoderHarness(_cobs_keeps_block), cover_depth=20, mutant_depth=10),
]
