"""On-chip TCSPC histogram with two banks in block RAM, or in single-port RAM (iCE40 SPRAM).

:class:`Histogram` takes the events and puts together its parts: the frame sequencer
(:mod:`~fliss.hdl.histogram.frames`), the bank storage and its counting pipeline
(:mod:`~fliss.hdl.histogram.banks`) and the readout (:mod:`~fliss.hdl.histogram.readout`).
"""

from amaranth.hdl import C, Cat, Module, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ..event import Event, TIMESTAMP_BITS
from .banks import SINGLE_LATENCY, SinglePortBanks
from .dual import LATENCY, DualPortBanks
from .frames import FrameSequencer
from .layout import (BANK_BITS, BIN_BITS, COUNT_WIDTH, INTEGRATION_WIDTH, MAX_BANK_BITS,
                     MAX_COUNT_WIDTH, MAX_SHIFT, MIN_COUNT_WIDTH, PIXEL_BITS, HistogramSettings,
                     ReadoutSplit, readout_layout)
from .readout import READOUT_CYCLES_PER_BIN, BankReadout, readout_cycles_per_bin
from ..tdc import COUNTER_WIDTH
from ..counters import count_event


__all__ = ["BANK_BITS", "MAX_BANK_BITS", "BIN_BITS", "COUNT_WIDTH", "MIN_COUNT_WIDTH",
           "MAX_COUNT_WIDTH", "MAX_SHIFT",
           "INTEGRATION_WIDTH", "LATENCY", "SINGLE_LATENCY", "READOUT_CYCLES_PER_BIN",
           "RAM_KINDS", "HistogramSettings", "ReadoutSplit", "readout_layout", "Histogram"]


#: Values of the ``ram`` parameter of :class:`Histogram`.
RAM_KINDS = ("dual", "single")


class Histogram(wiring.Component):
    """Per-pixel histograms of event timestamps, two banks in block RAM or in single-port RAM.

    A frame holds ``P = 2**pixel_bits`` pixels, the event addresses ``first_pixel …
    first_pixel + P - 1``, each of ``N = 2**n`` bins, ``n = 13 - shift``: bin ``b`` of pixel
    ``p`` counts the events with ``address - first_pixel == p`` and ``timestamp >> shift == b``,
    at flat index ``p << n | b`` of the bank. Events of other addresses are dropped and counted
    in ``dropped_pixel``. The split fits a bank of ``2**bank_bits`` bins when ``pixel_bits + n
    <= bank_bits`` (the register file refuses other settings); a frame whose split does not fit
    keeps ``2**q`` pixels, ``q = min(pixel_bits, bank_bits)`` (the others are dropped as out of
    the frame), of ``2**b`` bins, ``b = bank_bits - q`` (fewer than ``N``: events of the bins
    above are counted in ``overflow``), at flat index ``p << b | bin``. Counts saturate at
    ``2**count_width - 1``. A frame integrates the events of ``integration``
    consecutive clock cycles into the *fill* bank; the banks then swap and the frame is read out
    over ``readout`` while the next one fills the other bank, with no dead time, provided the
    readout of a frame ends before the next frame does.

    Dual-port banks (``ram="dual"``)
    ~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~
    Each bank is blocks of 1024 words, :class:`amaranth.lib.memory.Memory` with a read port and
    a write port (block RAM; :class:`~fliss.hdl.histogram.dual.DualPortBanks`). ``events`` is
    always ready: the engine takes one event in every clock cycle, also when consecutive events
    hit the same bin. Each event goes through a pipeline of :attr:`latency` stages (at most
    :data:`LATENCY`), each with little logic, for timing: pixel offset; range and window checks
    with the coarse shift and the pixel's place in the bank; fine shift to the flat index; block
    RAM read; in a bank of more than one block, each block's word registered as it leaves its
    block RAM, then OR-ed in a registered tree (a bank of 64 blocks spans the chip: two stages
    more); forwarding; saturating increment; block RAM write (every RAM input comes from a
    register). A read misses the writes of the four (six with the tree) events ahead of it, so
    their bins are compared with its own; on a match the event takes the newest of their counts
    (forwarding) instead of the stale RAM word.

    Single-port banks (``ram="single"``)
    ~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~
    Each bank is a :class:`~fliss.hdl.spram.SinglePortRam`: one ``SB_SPRAM256KA`` on the iCE40
    UltraPlus (16-bit counts only), where two 8192-bin banks do not fit the block RAM. A bank
    does one access per cycle, so an event needs two (read, then write) and the engine takes an
    event at most every other cycle, as fast as the TDC interfaces deliver them (an event per
    rising edge of a synchronised pin). ``events`` stays always ready: an event that arrives in
    the cycle right after one the engine took is dropped and counted in ``dropped`` and in
    ``dropped_busy``. Otherwise nothing changes: with events at least two cycles apart both
    kinds give the same frames, counters and readout.

    The accesses of the fill bank alternate between read slots and write slots. An event is
    range-checked and shifted to its bin in three stages, as with dual-port banks, then waits in
    a holding register for the next read slot (zero or one cycle); the RAM word is registered,
    incremented (saturating) and written back three cycles after the read, in a write slot. At
    most one event is in flight when an event reads its bin (the one that read two cycles
    earlier); on a match its new count is taken instead of the stale RAM word. From arrival to
    the write takes :data:`SINGLE_LATENCY` cycles at most. Every RAM input comes from a register,
    and the RAM word is registered before the increment. A read never uses the RAM output after
    a write cycle (see :class:`~fliss.hdl.spram.SinglePortRam`).

    The contents of ``SB_SPRAM256KA`` are undefined at power-up, so after reset the engine
    clears both banks, in ``2**bank_bits`` cycles (:attr:`init_cycles`): meanwhile no frame starts
    (``enable`` acts as if it rose in cycle :attr:`init_cycles`) and arriving events are counted
    in ``dropped``.

    Frames and banks
    ~~~~~~~~~~~~~~~~
    ``enable`` rising in cycle ``e`` starts the first frame in cycle ``e + 1``. A frame that
    starts in cycle ``s`` takes the events that arrive in cycles ``s … s + I - 1`` (``I`` =
    ``integration``, sampled at ``s - 1``; zero acts as one); then:

    * if the other bank is free (read out and cleared), the banks swap and the next frame starts
      in cycle ``s + I``;
    * otherwise the engine waits: events that arrive meanwhile are dropped and counted in
      ``dropped``, and the next frame starts in the cycle after the other bank is freed.

    ``enable`` falling in cycle ``d`` ends the frame in progress (events from ``d`` on are not
    counted in it); that shorter frame is read out like any other, even if it is empty because
    it started in cycle ``d``. ``shift`` is sampled with ``integration`` and holds for the whole
    frame, and so do ``pixel_bits`` and ``first_pixel``. Events that arrive while no frame is
    filling are counted in ``dropped``; then, of the others, events of an address outside the
    frame in ``dropped_pixel``, and events of a bin beyond their pixel's in ``overflow``.

    Readout
    ~~~~~~~
    A full bank is read out in flat index order, ``0 … P N - 1`` (pixel after pixel, each
    bin after bin); ``last`` marks the frame's final bin. ``readout_split`` gives
    the frame's settings meanwhile.
    Each bin is cleared as it is transferred, so the bank is empty when it fills again. The
    readout starts once the last events of the frame have left the pipeline and takes at least
    :attr:`readout_cycles_per_bin` cycles per bin: 4 (one read, one clearing write), plus the
    word's way through the read stages of a bank of more than one block (6, at most
    :data:`READOUT_CYCLES_PER_BIN`), so frames follow each other without dead time if
    ``integration`` is at least ``readout_cycles_per_bin * P N +`` :attr:`latency` ``+ 3``
    cycles plus the time the consumer holds ``ready`` low.

    Parameters
    ----------
    bank_bits : int
        Width of a bank's word address, from 1 to 19: ``2**bank_bits`` bins per bank (16, the
        default: 64 pixels of 1024 bins, or one of 8192).
    max_pixel_bits : int
        Largest ``pixel_bits`` the build takes, 0 to 6; with 0 (a smaller build) a frame is one
        pixel, the address ``first_pixel``, and ``settings.pixel_bits`` is not used.
    count_width : int
        Width of a bin count, from 16 to 32 bits; 16 with ``ram="single"``.
    ram : ``"dual"`` or ``"single"``
        Banks with a read port and a write port (block RAM), or single-port banks (iCE40
        SPRAM), which take an event at most every other cycle.
    read_tree : bool or None
        Dual-port banks of more than one block: whether each is its blocks and their read tree
        (``None``: on an ECP5) or one memory with the same timing
        (:class:`~fliss.hdl.histogram.dual.DualPortBanks`).

    Members
    -------
    events : In(stream.Signature(Event))
        Events; ``ready`` is always high.
    enable : In(1)
        Acquire frames.
    settings : In(HistogramSettings)
        ``integration``: frame length in clock cycles; ``bin_shift``: a bin is
        ``2**bin_shift`` timestamp codes wide; ``pixel_bits``, ``first_pixel``: the frame's
        pixels. All sampled when a frame starts (``full_readout`` is not used here).
    clear : In(1)
        Reset ``dropped``, ``dropped_busy``, ``dropped_pixel`` and ``overflow``.
    readout : Out(stream.Signature(readout_layout(bank_bits, count_width)))
        Bins of the frame being read out: flat ``index``, ``count``, ``last``.
    readout_split : Out(ReadoutSplit)
        Bin ``shift``, ``pixel_bits`` (``q``: the setting, unless the split does not fit the
        bank) and ``first_pixel`` of the frame being read out.
    filling : Out(1)
        A frame is filling in this cycle: an event that arrives now is counted (with
        ``ram="single"``: unless the engine took an event in the previous cycle).
    pending : Out(1)
        A completed frame waits to be read out or is being read out.
    frames : Out(32)
        Frames completed (handed to the readout) since reset; wraps around.
    dropped : Out(32)
        Events that arrived while no frame was filling, or (``ram="single"``) in the cycle
        right after an event the engine took (saturating).
    dropped_busy : Out(32)
        Of ``dropped``, the events that arrived in the cycle right after an event the engine
        took (saturating); always 0 with ``ram="dual"``. With ``ram="single"``, ``dropped``
        and ``dropped_busy`` count an event one cycle after its arrival (``clear`` in the
        cycle after an arrival counts it as the first).
    dropped_pixel : Out(32)
        Events taken in a frame whose address is not one of its pixels (saturating).
    overflow : Out(32)
        Events of a frame's pixel whose bin is beyond the pixel's bins (saturating; only with
        a split that does not fit the bank).
    tally : Out(data.StructLayout)
        One strobe per counter above, same names: high in each cycle the counter counts (and
        when it is full), for counters elsewhere.

    Attributes
    ----------
    banks : tuple of two :class:`amaranth.lib.memory.Memory` or :class:`~fliss.hdl.spram.SinglePortRam`
        Storage of the two banks, bank 0 filling first; testbenches may preload counts through
        ``banks[k].data`` (either kind).
    ram : str
        ``"dual"`` or ``"single"``.
    latency : int
        Most cycles from an event's arrival to the RAM write of its bin:
        :func:`~fliss.hdl.histogram.dual.latency` of the bank's read stages (at most
        :data:`LATENCY`) or :data:`SINGLE_LATENCY`.
    readout_cycles_per_bin : int
        Fewest cycles per bin of the readout,
        :func:`~fliss.hdl.histogram.readout.readout_cycles_per_bin` of the bank's read stages:
        4, or 6 with dual-port banks of more than one block (:data:`READOUT_CYCLES_PER_BIN`).
    min_event_spacing : int
        Fewest cycles between two events that are both counted: 1 or 2.
    init_cycles : int
        Cycles after reset before a frame can start: 0, or ``2**bank_bits`` with
        ``ram="single"`` (clearing the banks).
    bank_bits : int
        The parameter.
    """

    def __init__(self, *, bank_bits=BANK_BITS, count_width=COUNT_WIDTH, ram="dual",
                 max_pixel_bits=PIXEL_BITS, read_tree=None):
        if ram not in RAM_KINDS:
            raise ValueError(f"RAM kind must be one of {', '.join(map(repr, RAM_KINDS))}, "
                             f"not {ram!r}")
        if not isinstance(bank_bits, int) or not 1 <= bank_bits <= MAX_BANK_BITS:
            raise ValueError(f"Bank address width must be an integer from 1 to {MAX_BANK_BITS} "
                             f"bits, not {bank_bits!r}")
        if not isinstance(count_width, int) or \
                not MIN_COUNT_WIDTH <= count_width <= MAX_COUNT_WIDTH:
            raise ValueError(f"Count width must be an integer from {MIN_COUNT_WIDTH} to "
                             f"{MAX_COUNT_WIDTH} bits, not {count_width!r}")
        if not isinstance(max_pixel_bits, int) or not 0 <= max_pixel_bits <= PIXEL_BITS:
            raise ValueError(f"Most pixel bits must be an integer from 0 to {PIXEL_BITS}, "
                             f"not {max_pixel_bits!r}")
        self.max_pixel_bits = max_pixel_bits
        if ram == "single" and count_width != COUNT_WIDTH:
            raise ValueError(f"Count width must be {COUNT_WIDTH} bits with single-port RAM, "
                             f"not {count_width!r}")
        self.bank_bits = bank_bits
        self.count_width = count_width
        self.ram = ram
        if ram == "dual":
            self.min_event_spacing = 1
            storage = DualPortBanks(bank_bits, count_width, read_tree=read_tree)
        else:
            self.min_event_spacing = 2
            storage = SinglePortBanks(bank_bits, count_width)
        self._storage = storage
        self.latency = storage.latency
        self.readout_cycles_per_bin = readout_cycles_per_bin(storage.read_stages)
        self.init_cycles = storage.init_cycles
        self.banks = storage.banks
        super().__init__({
            "events":              In(stream.Signature(Event)),
            "enable":              In(1),
            "settings":            In(HistogramSettings),
            "clear":               In(1),
            "readout":             Out(stream.Signature(readout_layout(bank_bits, count_width))),
            "readout_split":       Out(ReadoutSplit),
            "filling":             Out(1),
            "pending":             Out(1),
            "frames":              Out(COUNTER_WIDTH),
            "dropped":             Out(COUNTER_WIDTH),
            "dropped_busy":        Out(COUNTER_WIDTH),
            "dropped_pixel":       Out(COUNTER_WIDTH),
            "overflow":            Out(COUNTER_WIDTH),
            "tally":               Out(data.StructLayout({
                                       "frames": 1, "dropped": 1, "dropped_busy": 1,
                                       "dropped_pixel": 1, "overflow": 1})),
        })

    def elaborate(self, platform):
        m = Module()

        single = self.ram == "single"
        m.submodules.sequencer = sequencer = FrameSequencer(self.bank_bits)
        m.submodules.storage = storage = self._storage
        m.submodules.reader = reader = BankReadout(self.bank_bits, self.count_width,
                                                   latency=self.latency, capture=single,
                                                   settle=storage.read_stages)

        # Frames and banks
        m.d.comb += [
            sequencer.enable.eq(self.enable),
            sequencer.integration.eq(self.settings.integration),
            sequencer.shift.eq(self.settings.bin_shift),
            sequencer.pixel_bits.eq(self.settings.pixel_bits if self.max_pixel_bits else 0),
            sequencer.first_pixel.eq(self.settings.first_pixel),
            sequencer.hold.eq(storage.initialising),
            sequencer.done.eq(reader.done),
            self.filling.eq(sequencer.filling),
            self.frames.eq(sequencer.frames),
            self.tally.frames.eq(sequencer.swap),
            self.pending.eq(sequencer.read_full),
            self.readout_split.shift.eq(sequencer.read_shift),
            self.readout_split.pixel_bits.eq(sequencer.read_pixel_bits),
            self.readout_split.first_pixel.eq(sequencer.read_first),
        ]
        arrive = Signal()
        m.d.comb += [
            self.events.ready.eq(1),
            arrive.eq(self.events.valid),
        ]

        # Stage 1: arrival, with the fill bank's settings and the pixel's offset in the frame.
        # Single-port banks: the engine takes no event in the cycle after it took one
        # (`valid1`).
        valid1 = Signal()
        timestamp1 = Signal(TIMESTAMP_BITS)
        offset1 = Signal(PIXEL_BITS + 1)            # address - first_pixel, borrow on top
        bank1 = Signal()
        shift1 = Signal(range(MAX_SHIFT + 1))
        mask1 = Signal(TIMESTAMP_BITS)
        pixels1 = Signal(PIXEL_BITS)
        position1 = Signal(range(TIMESTAMP_BITS + 1))
        if single:
            # drops are registered before they are counted (short paths from the sequencer)
            take = Signal()
            drop1 = Signal()
            busy1 = Signal()
            m.d.comb += take.eq(arrive & self.filling & ~valid1)
            m.d.sync += [
                drop1.eq(arrive & ~take),
                busy1.eq(arrive & self.filling & valid1),
            ]
            count_event(m, self.dropped, drop1, self.clear, self.tally.dropped)
            count_event(m, self.dropped_busy, busy1, self.clear, self.tally.dropped_busy)
        else:
            take = arrive & self.filling
            count_event(m, self.dropped, arrive & ~self.filling, self.clear, self.tally.dropped)
        m.d.sync += [
            valid1.eq(take),
            timestamp1.eq(self.events.payload.timestamp),
            offset1.eq(self.events.payload.address - sequencer.fill_first),
            bank1.eq(sequencer.fill_bank),
            shift1.eq(sequencer.fill_shift),
            mask1.eq(sequencer.fill_mask),
            pixels1.eq(sequencer.fill_pixels),
            position1.eq(sequencer.fill_position),
        ]

        # Stage 2: window and range checks, coarse shift (by a multiple of 4), the pixel's
        # first bin in the bank (`pixel << b`)
        valid2 = Signal()
        coarse2 = Signal(TIMESTAMP_BITS)
        fine2 = Signal(2)
        base2 = Signal(self.bank_bits)
        bank2 = Signal()
        in_window = Signal()
        in_range = Signal()
        if self.max_pixel_bits:
            m.d.comb += in_window.eq(~offset1[-1] & ((offset1[:PIXEL_BITS] & pixels1) == 0))
        else:       # (one pixel, selected by its address: no pixel logic)
            m.d.comb += in_window.eq(offset1 == 0)
        m.d.comb += in_range.eq((timestamp1 & mask1) == 0)
        m.d.sync += [
            valid2.eq(valid1 & in_window & in_range),
            coarse2.eq(timestamp1 >> Cat(C(0, 2), shift1[2:])),
            fine2.eq(shift1[:2]),
            base2.eq(offset1[:PIXEL_BITS] << position1 if self.max_pixel_bits else 0),
            bank2.eq(bank1),
        ]
        count_event(m, self.dropped_pixel, valid1 & ~in_window, self.clear,
                    self.tally.dropped_pixel)
        count_event(m, self.overflow, valid1 & in_window & ~in_range, self.clear,
                    self.tally.overflow)
        # the flat index: the bin is below 2**b, so it fills the bits below the pixel's
        index2 = Signal(self.bank_bits)
        m.d.comb += index2.eq(base2 | (coarse2 >> fine2))

        # Counting in the banks, readout of the other bank
        m.d.comb += [
            storage.valid.eq(valid2),
            storage.bin.eq(index2),
            storage.bank.eq(bank2),
            storage.readout_bank.eq(sequencer.read_bank),
            storage.readout_index.eq(reader.index),
            storage.readout_read.eq(reader.address),
            storage.readout_clear.eq(reader.clear),
            reader.swap.eq(sequencer.swap),
            reader.full.eq(sequencer.read_full),
            reader.last.eq(sequencer.read_last),
            reader.word.eq(storage.word),
        ]
        wiring.connect(m, reader.readout, wiring.flipped(self.readout))

        return m
