"""Formal harnesses of the histogram engine (``hdl/histogram/engine.py`` with its frame sequencer,
banks and readout), with small parameters: two bins (``bank_bits = 1``), 16-bit counts,
dual-port or single-port banks, frames of one to :data:`MAX_INTEGRATION` cycles (the
single-port accounting: :data:`SINGLE_INTEGRATION`). Without a platform the single-port banks
are the generic model of ``hdl/spram.py`` (a :class:`~amaranth.lib.memory.Memory`), not an
``SB_SPRAM256KA`` black box.

Inputs are free in every cycle: events (any timestamp and address), ``enable``, the settings
(within the register file's ranges: any pixel split, fitting the bank or not) and the readout's
backpressure; ``clear`` stays low (it resets the drop
counters, which the accounting reads). Mutants override a block's own statements
(:func:`._harness.open_block`).
"""

from amaranth.hdl import Assert, Assume, Cover, Module, Mux, ResetSignal, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In

from ..hdl.histogram.engine import Histogram
from ..hdl.histogram.layout import MAX_SHIFT, PIXEL_BITS, HistogramSettings

from ._harness import assigned, copy_of, fsm, open_block, open_submodule, past
from .runner import Proof


#: Longest frame of the harness, in cycles.
MAX_INTEGRATION = 2

#: Longest frame of the single-port harness's accounting: two events (two cycles apart) in
#: one frame, so that the second one's count is forwarded from the first.
SINGLE_INTEGRATION = 3

#: Timestamp width of the harness: enough for both bins and overflow above them.
TIMESTAMP_BITS = 3

#: Address width of the harness: pixels 0 … 3 (a frame of the 1-bit bank holds at most two).
ADDRESS_BITS = 2

#: Width of the harness's event accounting (no wrap within the BMC depth).
TALLY_WIDTH = 6


def _counted_twice(block, module):
    # each event's bin is written with its count plus two (into the RAM and the forwarding
    # register both)
    new, written, valid_e, bank_e = assigned(module, "new", "written", "valid_e", "bank_e")
    module.d.sync += written.eq(new + 1)
    for k in range(2):
        write_data, = assigned(module, f"write_data{k}")
        with module.If(valid_e & (bank_e == k)):
            module.d.sync += write_data.eq(new + 1)


def _count_into_readout(block, module):
    # an event of the next frame is counted into the bank being read out
    bank_e, = assigned(module, "bank_e")
    module.d.sync += bank_e.eq(block.readout_bank)


def _single_stages(module):
    # the (valid, bank) registers of stages A, D and Q of the single-port banks' pipeline
    # (registered copies of the read issued from stage R)
    issue, bank = assigned(module, "issue", "bank_a")
    valid = copy_of(module, issue)
    stages = [(valid, bank)]
    for _ in "dq":
        valid, bank = copy_of(module, valid), copy_of(module, bank)
        stages.append((valid, bank))
    return stages


def _single_counted_twice(block, module):
    # single-port banks: each event's RAM word is taken one too high (written plus two)
    (_, bank_d), stored_q = _single_stages(module)[1], assigned(module, "stored_q")[0]
    words = [bank.read_data for bank in block.banks]
    module.d.sync += stored_q.eq(Mux(bank_d, words[1], words[0]) + 1)


def _single_count_into_readout(block, module):
    # single-port banks: an event of the next frame is counted into the bank being read out
    _, bank_q = _single_stages(module)[2]
    module.d.sync += bank_q.eq(block.readout_bank)


class HistogramHarness(wiring.Component):
    """The histogram engine on free inputs.

    ``check`` is ``"count"``: whenever the engine is at rest (no frame filling or waiting to be
    read out, for a cycle), the events that arrived equal the counts read out plus ``dropped``,
    ``dropped_pixel`` and ``overflow``: every event is counted exactly once; or ``"bank"``: no event is ever
    counted into the bank being read out. ``ram`` is the banks' kind (``Histogram``'s
    parameter); with ``"single"`` the accounting splits the events by whether a frame was
    filling when they arrived (those counted in a bin, in ``overflow`` or in ``dropped_busy``,
    the others in the rest of ``dropped``), one cycle late (the drop counters are). Pixel
    addresses are narrowed to :data:`ADDRESS_BITS` (below and at the bank's pixels, and past
    them; the first pixel is free too).
    """

    events_valid: In(1)
    timestamp:    In(13)
    address:      In(PIXEL_BITS)
    enable:       In(1)
    settings:     In(HistogramSettings)
    ready:        In(1)

    def __init__(self, check, mutate=None, *, ram="dual", max_integration=MAX_INTEGRATION):
        self.check, self.mutate, self.ram = check, mutate, ram
        self.max_integration = max_integration
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        dut = Histogram(bank_bits=1, count_width=16, ram=self.ram)
        m.submodules.dut = module = open_block(dut, platform=platform)
        storage, banks = open_submodule(module, "storage", self.mutate, platform)
        reader, readout = open_submodule(module, "reader", platform=platform)
        m.d.comb += [
            dut.events.valid.eq(self.events_valid),
            dut.events.payload.timestamp.eq(self.timestamp),
            dut.events.payload.address.eq(self.address),
            dut.enable.eq(self.enable),
            dut.settings.eq(self.settings),
            dut.readout.ready.eq(self.ready),
            dut.clear.eq(0),
            Assume(~ResetSignal("sync")),
            Assume(self.settings.integration <= self.max_integration),
            Assume(self.settings.bin_shift <= MAX_SHIFT),
            Assume(self.timestamp < (1 << TIMESTAMP_BITS)),
            Assume(self.address < (1 << ADDRESS_BITS)),
            Assume(self.settings.first_pixel < (1 << ADDRESS_BITS)),
            Assume(self.settings.pixel_bits <= PIXEL_BITS),
        ]

        if self.check == "count":
            self._count(m, dut, module)
        elif self.ram == "dual":
            self._bank_dual(m, dut, module, banks, readout)
        else:
            self._bank_single(m, dut, module, banks, readout)
        return m

    def _count(self, m, dut, module):
        read = Signal(TALLY_WIDTH)
        with m.If(dut.readout.valid & dut.readout.ready):
            m.d.sync += read.eq(read + dut.readout.payload.count)
        # at rest: the sequencer idle (no frame filling or waiting for a bank), no frame
        # being read out (its readout waits for the pipeline to drain)
        _, sequencer = open_submodule(module, "sequencer")
        _, is_sequencer = fsm(sequencer)
        rest = Signal()
        m.d.comb += rest.eq(is_sequencer("IDLE") & ~dut.pending)
        m.d.comb += [
            Cover(rest & (read == 2)),          # two events in one frame, read out
            Cover(rest & (dut.overflow != 0)),
            Cover(rest & (dut.dropped != 0)),
            Cover(rest & (dut.dropped_pixel != 0)),
            Cover(rest & (read == 2) & (self.settings.pixel_bits == 1)),   # two pixels
        ]
        if self.ram == "dual":
            arrived = Signal(TALLY_WIDTH)
            with m.If(dut.events.valid):
                m.d.sync += arrived.eq(arrived + 1)
            balance = Signal(TALLY_WIDTH)
            m.d.comb += balance.eq(read + dut.dropped + dut.dropped_pixel + dut.overflow)
            m.d.comb += Assert(~rest | (arrived == balance))
            return
        # single-port banks: the drop counters count an event one cycle after its arrival
        # (registered), so are the events that arrived (until the previous cycle)
        arrived_filling = Signal(TALLY_WIDTH)   # a frame was filling: taken, or busy
        arrived_idle = Signal(TALLY_WIDTH)      # no frame was filling
        valid, filling = past(m, dut.events.valid), past(m, dut.filling)
        with m.If(valid & filling):
            m.d.sync += arrived_filling.eq(arrived_filling + 1)
        with m.If(valid & ~filling):
            m.d.sync += arrived_idle.eq(arrived_idle + 1)
        counted, idle = Signal(TALLY_WIDTH), Signal(TALLY_WIDTH)
        m.d.comb += [
            counted.eq(read + dut.overflow + dut.dropped_pixel + dut.dropped_busy),
            idle.eq(dut.dropped - dut.dropped_busy),
            Assert(dut.dropped_busy <= dut.dropped),
            Assert(~rest | ((arrived_filling == counted) & (arrived_idle == idle))),
            Cover(rest & (dut.dropped_busy != 0)),
        ]

    def _bank_dual(self, m, dut, module, banks, readout):
        reader_state, is_reading = fsm(readout)
        # Invariants (for the induction): an event tagged with the bank being read out is
        # at most `drain` cycles from its write, and the readout starts once it is written
        read_bank = dut._storage.readout_bank
        drain, start_read = assigned(readout, "drain", "start_read")
        stages = [assigned(module, "valid1", "bank1"), assigned(module, "valid2", "bank2")]
        valid, bank = assigned(banks, "valid_r", "bank_r")
        stages.append((valid, bank))
        while len(stages) < dut.latency:    # (stages D, the read stages, Q, E, W: registered
            valid, bank = copy_of(banks, valid), copy_of(banks, bank)   # copies of R's)
            stages.append((valid, bank))
        if self.mutate is None:
            for age, (valid, bank) in enumerate(stages, start=1):
                m.d.comb += Assert(~(valid & (bank == read_bank)) |
                                   (drain >= dut.latency + 1 - age))
            m.d.comb += [
                Assert(reader_state < 5),
                Assert(is_reading("IDLE") | ((drain == 0) & dut.pending)),
                Assert(~start_read | (drain == 0)),
            ]
        for k in range(2):
            # a count the pipeline writes is at least 1 (it saturates); the readout writes 0
            write_enable, write_data = assigned(banks, f"write_enable{k}", f"write_data{k}")
            counting = write_enable & (write_data != 0)
            busy = ~is_reading("IDLE") & (dut._storage.readout_bank == k)
            m.d.comb += [
                Assert(~(counting & busy)),
                Cover(counting & (dut._storage.readout_bank == k) & dut.pending),
            ]


    def _bank_single(self, m, dut, module, banks, readout):
        reader_state, is_reading = fsm(readout)
        storage = dut._storage
        read_bank = storage.readout_bank
        (valid_a, bank_a), (valid_d, bank_d), (valid_q, bank_q) = _single_stages(banks)
        # Invariants (for the induction), as with dual-port banks; the bin waits in stage R
        # until a read slot (`read_slot`: the next cycle is one), so it needs a cycle more there
        # unless the next cycle is one
        if self.mutate is None:
            drain, start_read, read_slot = assigned(readout, "drain", "start_read") + \
                assigned(banks, "read_slot")
            valid_r, bank_r = assigned(banks, "valid_r", "bank_r")
            stages = [(*assigned(module, "valid1", "bank1"), 8),
                      (*assigned(module, "valid2", "bank2"), 7),
                      (valid_a, bank_a, 4),
                      (valid_d, bank_d, 3),
                      (valid_q, bank_q, 2)]
            for valid, bank, least in stages:
                m.d.comb += Assert(~(valid & (bank == read_bank)) | (drain >= least))
            m.d.comb += [
                Assert(~(valid_r & (bank_r == read_bank)) | (drain >= Mux(read_slot, 5, 6))),
                Assert(reader_state < 5),
                Assert(is_reading("IDLE") | ((drain == 0) & dut.pending)),
                Assert(~start_read | (drain == 0)),
            ]
        for k in range(2):
            # the bank's RAM inputs (registers) hold a write of the pipeline in this cycle
            counting = Signal(name=f"counting{k}")
            m.d.sync += counting.eq(~storage.initialising & valid_q & (bank_q == k))
            busy = ~is_reading("IDLE") & (read_bank == k)
            m.d.comb += [
                Assert(~(counting & busy)),
                Cover(counting & (read_bank == k) & dut.pending),
            ]


PROOFS = [
    Proof("histogram.counted_once", lambda: HistogramHarness("count"), "bmc", 30,
          "histogram: every event counted once, in a bin read out, dropped, dropped_pixel or "
          "overflow",
          mutant=lambda: HistogramHarness("count", _counted_twice), mutant_depth=20),
    Proof("histogram.readout_bank", lambda: HistogramHarness("bank"), "prove", 4,
          "histogram: no event is counted into the bank being read out",
          mutant=lambda: HistogramHarness("bank", _count_into_readout), cover_depth=24),
    Proof("histogram.counted_once_single",
          lambda: HistogramHarness("count", ram="single", max_integration=SINGLE_INTEGRATION),
          "bmc", 34,
          "histogram, single-port banks: every event counted once, in a bin read out, "
          "overflow, dropped_pixel, dropped_busy or dropped",
          mutant=lambda: HistogramHarness("count", _single_counted_twice, ram="single",
                                         max_integration=SINGLE_INTEGRATION),
          mutant_depth=20),
    Proof("histogram.readout_bank_single", lambda: HistogramHarness("bank", ram="single"),
          "prove", 4,
          "histogram, single-port banks: no event is counted into the bank being read out",
          mutant=lambda: HistogramHarness("bank", _single_count_into_readout, ram="single"),
          cover_depth=24),
]
