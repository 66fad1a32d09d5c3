"""Formal harnesses of the histogram engine (``hdl/histogram.py`` with its frame sequencer,
banks and readout), with small parameters: two bins (``bin_bits = 1``), 16-bit counts,
dual-port banks, frames of one to :data:`MAX_INTEGRATION` cycles.

Inputs are free in every cycle: events (any timestamp), ``enable``, the settings (within the
register file's ranges) and the readout's backpressure; ``clear`` stays low (it resets the drop
counters, which the accounting reads). Mutants override a block's own statements
(:func:`._harness.open_block`).
"""

from amaranth.hdl import Assert, Assume, Cover, Module, ResetSignal, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In

from fliss.hdl.histogram import Histogram
from fliss.hdl.histogram_layout import MAX_SHIFT, HistogramSettings

from ._harness import assigned, copy_of, fsm, open_block, open_submodule
from .runner import Proof


#: Longest frame of the harness, in cycles.
MAX_INTEGRATION = 2

#: Timestamp width of the harness: enough for both bins and overflow above them.
TIMESTAMP_BITS = 3

#: Width of the harness's event accounting (no wrap within the BMC depth).
TALLY_WIDTH = 6


def _counted_twice(block, module):
    # each event's bin is written with its count plus two
    new, written = assigned(module, "new", "written")
    module.d.sync += written.eq(new + 1)


def _count_into_readout(block, module):
    # an event of the next frame is counted into the bank being read out
    bank_e, = assigned(module, "bank_e")
    module.d.sync += bank_e.eq(block.readout_bank)


class HistogramHarness(wiring.Component):
    """The histogram engine on free inputs.

    ``check`` is ``"count"``: whenever the engine is at rest (no frame filling or waiting to be
    read out, for a cycle), the events that arrived equal the counts read out plus ``dropped``
    and ``overflow``: every event is counted exactly once; or ``"bank"``: no event is ever
    counted into the bank being read out.
    """

    events_valid: In(1)
    timestamp:    In(13)
    enable:       In(1)
    settings:     In(HistogramSettings)
    ready:        In(1)

    def __init__(self, check, mutate=None):
        self.check, self.mutate = check, mutate
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        dut = Histogram(bin_bits=1, count_width=16)
        m.submodules.dut = module = open_block(dut, platform=platform)
        storage, banks = open_submodule(module, "storage", self.mutate, platform)
        reader, readout = open_submodule(module, "reader", platform=platform)
        m.d.comb += [
            dut.events.valid.eq(self.events_valid),
            dut.events.payload.timestamp.eq(self.timestamp),
            dut.enable.eq(self.enable),
            dut.settings.eq(self.settings),
            dut.readout.ready.eq(self.ready),
            dut.clear.eq(0),
            Assume(~ResetSignal("sync")),
            Assume(self.settings.integration <= MAX_INTEGRATION),
            Assume(self.settings.bin_shift <= MAX_SHIFT),
            Assume(self.timestamp < (1 << TIMESTAMP_BITS)),
        ]

        if self.check == "count":
            arrived = Signal(TALLY_WIDTH)
            read = Signal(TALLY_WIDTH)
            with m.If(dut.events.valid):
                m.d.sync += arrived.eq(arrived + 1)
            with m.If(dut.readout.valid & dut.readout.ready):
                m.d.sync += read.eq(read + dut.readout.payload.count)
            # at rest: the sequencer idle (no frame filling or waiting for a bank), no frame
            # being read out (its readout waits for the pipeline to drain)
            _, sequencer = open_submodule(module, "sequencer", platform=platform)
            _, is_sequencer = fsm(sequencer)
            rest = Signal()
            m.d.comb += rest.eq(is_sequencer("IDLE") & ~dut.pending)
            balance = Signal(TALLY_WIDTH)
            m.d.comb += balance.eq(read + dut.dropped + dut.overflow)
            m.d.comb += [
                Assert(~rest | (arrived == balance)),
                Cover(rest & (read == 2)),          # two events in one frame, read out
                Cover(rest & (dut.overflow != 0)),
                Cover(rest & (dut.dropped != 0)),
            ]
        else:
            reader_state, is_reading = fsm(readout)
            # Invariants (for the induction): an event tagged with the bank being read out is
            # at most `drain` cycles from its write, and the readout starts once it is written
            read_bank = dut._storage.readout_bank
            drain, start_read = assigned(readout, "drain", "start_read")
            stages = [assigned(module, "valid1", "bank1"), assigned(module, "valid2", "bank2")]
            valid, bank = assigned(banks, "valid_r", "bank_r")
            stages.append((valid, bank))
            for _ in "dqew":    # (stages D, Q, E, W: registered copies of R's)
                valid, bank = copy_of(banks, valid), copy_of(banks, bank)
                stages.append((valid, bank))
            if self.mutate is None:
                for age, (valid, bank) in enumerate(stages, start=1):
                    m.d.comb += Assert(~(valid & (bank == read_bank)) | (drain >= 8 - age))
                m.d.comb += [
                    Assert(reader_state < 5),
                    Assert(is_reading("IDLE") | ((drain == 0) & dut.pending)),
                    Assert(~start_read | (drain == 0)),
                ]
            for k in range(2):
                write_enable, write_zero = assigned(banks, f"write_enable{k}", f"write_zero{k}")
                busy = ~is_reading("IDLE") & (dut._storage.readout_bank == k)
                m.d.comb += [
                    Assert(~(write_enable & ~write_zero & busy)),
                    Cover(write_enable & ~write_zero & (dut._storage.readout_bank == k) &
                          dut.pending),
                ]
        return m


PROOFS = [
    Proof("histogram.counted_once", lambda: HistogramHarness("count"), "bmc", 30,
          "histogram: every event counted once, in a bin read out, dropped or overflow",
          mutant=lambda: HistogramHarness("count", _counted_twice), mutant_depth=20),
    Proof("histogram.readout_bank", lambda: HistogramHarness("bank"), "prove", 4,
          "histogram: no event is counted into the bank being read out",
          mutant=lambda: HistogramHarness("bank", _count_into_readout), cover_depth=24),
]
