"""On-chip TCSPC histogram with two banks in block RAM, or in single-port RAM (iCE40 SPRAM)."""

from amaranth.hdl import *
from amaranth.lib import data, stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from .event import Event, TIMESTAMP_BITS
from .spram import SinglePortRam
from .tdc import COUNTER_WIDTH, count_event


__all__ = ["BIN_BITS", "COUNT_WIDTH", "MIN_COUNT_WIDTH", "MAX_COUNT_WIDTH", "MAX_SHIFT",
           "INTEGRATION_WIDTH", "LATENCY", "SINGLE_LATENCY", "READOUT_CYCLES_PER_BIN",
           "RAM_KINDS", "readout_layout", "Histogram"]


#: Default bin index width: one bin per timestamp code, 8192 bins.
BIN_BITS = TIMESTAMP_BITS
#: Default width of a bin count, in bits.
COUNT_WIDTH = 16
#: Narrowest bin count, in bits.
MIN_COUNT_WIDTH = 16
#: Widest bin count, in bits.
MAX_COUNT_WIDTH = 32
#: Largest bin shift: with it every timestamp falls in bin 0.
MAX_SHIFT = TIMESTAMP_BITS
#: Width of the integration time setting, in clock cycles: up to 53 s at 80 MHz.
INTEGRATION_WIDTH = 32
#: Cycles from an event's transfer on ``events`` to the block RAM write of its bin
#: (``ram="dual"``).
LATENCY = 7
#: Most cycles from an event's transfer on ``events`` to the RAM write of its bin, with
#: ``ram="single"``.
SINGLE_LATENCY = 8
#: Clock cycles per bin on ``readout`` when its consumer is always ready (both RAM kinds).
READOUT_CYCLES_PER_BIN = 4
#: Values of the ``ram`` parameter of :class:`Histogram`.
RAM_KINDS = ("dual", "single")


def readout_layout(bin_bits=BIN_BITS, count_width=COUNT_WIDTH):
    """Payload of :attr:`Histogram.readout`: bin index, count, last bin of the frame."""
    return data.StructLayout({
        "index": bin_bits,
        "count": count_width,
        "last":  1,
    })


class Histogram(wiring.Component):
    """Histogram of event timestamps, two banks in block RAM or in single-port RAM.

    Bin ``b`` of a frame counts the events whose ``timestamp >> shift`` equals ``b``. Counts
    saturate at ``2**count_width - 1``. A frame integrates the events of ``integration``
    consecutive clock cycles into the *fill* bank; the banks then swap and the frame is read out
    over ``readout`` while the next one fills the other bank, with no dead time, provided the
    readout of a frame ends before the next frame does.

    Dual-port banks (``ram="dual"``)
    ~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~
    Each bank is an :class:`amaranth.lib.memory.Memory` with a read port and a write port (block
    RAM). ``events`` is always ready: the engine takes one event in every clock cycle, also when
    consecutive events hit the same bin. Each event goes through a pipeline of :data:`LATENCY`
    stages, each with little logic, for timing on small FPGAs: range check and coarse shift, fine
    shift to the bin index, block RAM read, RAM word registered as it leaves the block RAM,
    forwarding, saturating increment, block RAM write (every RAM input comes from a register).
    A read misses the writes of the four events ahead of it, so their bins are compared with its
    own; on a match the event takes the newest of their counts (forwarding) instead of the stale
    RAM word.

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
    clears both banks, in ``2**bin_bits`` cycles (:attr:`init_cycles`): meanwhile no frame starts
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
    frame. Events that arrive while no frame is filling are counted in ``dropped``; events whose
    bin is beyond the RAM are counted in ``overflow``.

    Readout
    ~~~~~~~
    A full bank is read out in bin order, bins ``0 … n - 1`` with ``n = 2**min(bin_bits,
    13 - shift)``; ``last`` marks bin ``n - 1``. Each bin is cleared as it is transferred, so the
    bank is empty when it fills again. The readout starts once the last events of the frame have
    left the pipeline and takes at least :data:`READOUT_CYCLES_PER_BIN` cycles per bin (both RAM
    kinds: one read and one clearing write per bin), so frames follow each other without dead
    time if ``integration`` is at least ``4 n +`` :attr:`latency` ``+ 3`` cycles plus the time
    the consumer holds ``ready`` low.

    Parameters
    ----------
    bin_bits : int
        Width of the bin index, from 1 to 13: ``2**bin_bits`` bins per bank. 13 holds every
        timestamp code; smaller FPGAs use fewer bins together with a ``shift``.
    count_width : int
        Width of a bin count, from 16 to 32 bits; 16 with ``ram="single"``.
    ram : ``"dual"`` or ``"single"``
        Banks with a read port and a write port (block RAM), or single-port banks (iCE40
        SPRAM), which take an event at most every other cycle.

    Members
    -------
    events : In(stream.Signature(Event))
        Events; ``ready`` is always high.
    enable : In(1)
        Acquire frames.
    integration : In(32)
        Frame length in clock cycles, sampled when a frame starts.
    shift : In(range(14))
        Bin shift: a bin is ``2**shift`` timestamp codes wide. Sampled when a frame starts.
    clear : In(1)
        Reset ``dropped``, ``dropped_busy`` and ``overflow``.
    readout : Out(stream.Signature(readout_layout(bin_bits, count_width)))
        Bins of the frame being read out: ``index``, ``count``, ``last``.
    readout_shift : Out(range(14))
        Bin shift of the frame being read out.
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
    overflow : Out(32)
        Events whose bin is beyond ``2**bin_bits - 1`` (saturating).
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
        Most cycles from an event's arrival to the RAM write of its bin: :data:`LATENCY` or
        :data:`SINGLE_LATENCY`.
    readout_cycles_per_bin : int
        :data:`READOUT_CYCLES_PER_BIN`.
    min_event_spacing : int
        Fewest cycles between two events that are both counted: 1 or 2.
    init_cycles : int
        Cycles after reset before a frame can start: 0, or ``2**bin_bits`` with
        ``ram="single"`` (clearing the banks).
    """

    def __init__(self, *, bin_bits=BIN_BITS, count_width=COUNT_WIDTH, ram="dual"):
        if ram not in RAM_KINDS:
            raise ValueError(f"RAM kind must be one of {', '.join(map(repr, RAM_KINDS))}, "
                             f"not {ram!r}")
        if not isinstance(bin_bits, int) or not 1 <= bin_bits <= TIMESTAMP_BITS:
            raise ValueError(f"Bin index width must be an integer from 1 to {TIMESTAMP_BITS} "
                             f"bits, not {bin_bits!r}")
        if not isinstance(count_width, int) or \
                not MIN_COUNT_WIDTH <= count_width <= MAX_COUNT_WIDTH:
            raise ValueError(f"Count width must be an integer from {MIN_COUNT_WIDTH} to "
                             f"{MAX_COUNT_WIDTH} bits, not {count_width!r}")
        if ram == "single" and count_width != COUNT_WIDTH:
            raise ValueError(f"Count width must be {COUNT_WIDTH} bits with single-port RAM, "
                             f"not {count_width!r}")
        self.bin_bits = bin_bits
        self.count_width = count_width
        self.ram = ram
        self.readout_cycles_per_bin = READOUT_CYCLES_PER_BIN
        if ram == "dual":
            self.latency = LATENCY
            self.min_event_spacing = 1
            self.init_cycles = 0
        else:
            self.latency = SINGLE_LATENCY
            self.min_event_spacing = 2
            self.init_cycles = 1 << bin_bits
        super().__init__({
            "events":        In(stream.Signature(Event)),
            "enable":        In(1),
            "integration":   In(INTEGRATION_WIDTH),
            "shift":         In(range(MAX_SHIFT + 1)),
            "clear":         In(1),
            "readout":       Out(stream.Signature(readout_layout(bin_bits, count_width))),
            "readout_shift": Out(range(MAX_SHIFT + 1)),
            "filling":       Out(1),
            "pending":       Out(1),
            "frames":        Out(COUNTER_WIDTH),
            "dropped":       Out(COUNTER_WIDTH),
            "dropped_busy":  Out(COUNTER_WIDTH),
            "overflow":      Out(COUNTER_WIDTH),
            "tally":         Out(data.StructLayout({
                                 "frames": 1, "dropped": 1, "dropped_busy": 1, "overflow": 1})),
        })
        if ram == "dual":
            self.banks = tuple(Memory(shape=count_width, depth=1 << bin_bits, init=[])
                               for _ in range(2))
        else:
            self.banks = tuple(SinglePortRam(depth=1 << bin_bits, width=count_width)
                               for _ in range(2))

    def elaborate(self, platform):
        m = Module()

        single = self.ram == "single"
        count_max = (1 << self.count_width) - 1

        for k, bank in enumerate(self.banks):
            m.submodules[f"bank{k}"] = bank
        if single:
            bank_data = [bank.read_data for bank in self.banks]
        else:
            banks = [(memory.read_port(), memory.write_port()) for memory in self.banks]
            bank_data = [read_port.data for read_port, _ in banks]

        # Single-port banks start undefined: clear both after reset, before the first frame.
        initialising = Signal(init=int(single))
        init_index = Signal(self.bin_bits)
        if single:
            with m.If(initialising):
                m.d.sync += init_index.eq(init_index + 1)
                with m.If(init_index == (1 << self.bin_bits) - 1):
                    m.d.sync += initialising.eq(0)

        # Bank state: `fill_bank` fills, the other one is read out; `full[k]`: bank k holds a
        # completed frame that is not yet entirely read out and cleared.
        fill_bank = Signal()
        read_bank = Signal()
        full = Signal(2)
        m.d.comb += read_bank.eq(~fill_bank)
        other_free = Signal()
        m.d.comb += other_free.eq(~full.bit_select(read_bank, 1))

        # Per-bank settings, sampled when a frame starts in that bank
        bank_shift = Array(Signal(range(MAX_SHIFT + 1), name=f"bank{k}_shift") for k in range(2))
        bank_last = Array(Signal(self.bin_bits, name=f"bank{k}_last") for k in range(2))
        bank_mask = Array(Signal(TIMESTAMP_BITS, name=f"bank{k}_mask") for k in range(2))
        last_for_shift = Signal(self.bin_bits)   # last bin read out
        mask_for_shift = Signal(TIMESTAMP_BITS)  # timestamp bits that put the bin beyond the RAM
        with m.Switch(self.shift):
            for shift in range(MAX_SHIFT + 1):
                with m.Case(shift):
                    used = min(self.bin_bits, TIMESTAMP_BITS - shift)
                    kept = min(TIMESTAMP_BITS, self.bin_bits + shift)
                    m.d.comb += [
                        last_for_shift.eq((1 << used) - 1),
                        mask_for_shift.eq(((1 << TIMESTAMP_BITS) - 1) & ~((1 << kept) - 1)),
                    ]
            with m.Default():
                m.d.comb += last_for_shift.eq(0), mask_for_shift.eq(0)

        remaining = Signal(INTEGRATION_WIDTH)   # cycles left in the frame, this one included
        final = Signal()                        # this is the last cycle of the frame
        swap = Signal()
        start_frame = Signal()
        new_bank = Signal()
        with m.If(swap):
            m.d.sync += [
                fill_bank.eq(~fill_bank),
                full.bit_select(fill_bank, 1).eq(1),
                self.frames.eq(self.frames + 1),
            ]
            m.d.comb += self.tally.frames.eq(1)
        m.d.comb += new_bank.eq(fill_bank ^ swap)
        with m.If(start_frame):
            m.d.sync += [
                remaining.eq(self.integration),
                final.eq(self.integration <= 1),
                bank_shift[new_bank].eq(self.shift),
                bank_last[new_bank].eq(last_for_shift),
                bank_mask[new_bank].eq(mask_for_shift),
            ]

        # Frame sequencer
        arrive = Signal()
        m.d.comb += [
            self.events.ready.eq(1),
            arrive.eq(self.events.valid),
        ]
        with m.FSM():
            with m.State("IDLE"):
                with m.If(self.enable & ~initialising):
                    m.d.comb += start_frame.eq(1)
                    m.next = "FILL"
            with m.State("FILL"):
                with m.If(~self.enable):
                    with m.If(other_free):
                        m.d.comb += swap.eq(1)
                        m.next = "IDLE"
                    with m.Else():
                        m.next = "STOP"
                with m.Else():
                    m.d.comb += self.filling.eq(1)
                    with m.If(final):
                        with m.If(other_free):
                            m.d.comb += [swap.eq(1), start_frame.eq(1)]
                        with m.Else():
                            m.next = "WAIT"
                    with m.Else():
                        m.d.sync += [
                            remaining.eq(remaining - 1),
                            final.eq(remaining == 2),
                        ]
            with m.State("WAIT"):
                with m.If(other_free):
                    m.d.comb += swap.eq(1)
                    with m.If(self.enable):
                        m.d.comb += start_frame.eq(1)
                        m.next = "FILL"
                    with m.Else():
                        m.next = "IDLE"
            with m.State("STOP"):
                with m.If(other_free):
                    m.d.comb += swap.eq(1)
                    m.next = "IDLE"

        # Stage 1: arrival, with the fill bank's settings. Single-port banks: the engine takes no
        # event in the cycle after it took one (`valid1`).
        valid1 = Signal()
        timestamp1 = Signal(TIMESTAMP_BITS)
        bank1 = Signal()
        shift1 = Signal(range(MAX_SHIFT + 1))
        mask1 = Signal(TIMESTAMP_BITS)
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
            bank1.eq(fill_bank),
            shift1.eq(bank_shift[fill_bank]),
            mask1.eq(bank_mask[fill_bank]),
        ]

        # Stage 2: range check, coarse shift (by a multiple of 4)
        valid2 = Signal()
        coarse2 = Signal(TIMESTAMP_BITS)
        fine2 = Signal(2)
        bank2 = Signal()
        in_range = Signal()
        m.d.comb += in_range.eq((timestamp1 & mask1) == 0)
        m.d.sync += [
            valid2.eq(valid1 & in_range),
            coarse2.eq(timestamp1 >> Cat(C(0, 2), shift1[2:])),
            fine2.eq(shift1[:2]),
            bank2.eq(bank1),
        ]
        count_event(m, self.overflow, valid1 & ~in_range, self.clear, self.tally.overflow)
        bin2 = Signal(self.bin_bits)
        m.d.comb += bin2.eq(coarse2 >> fine2)

        def increment(value, name):
            total = Signal(self.count_width + 1, name=f"{name}_total")
            m.d.comb += total.eq(value + 1)
            return Mux(total[-1], count_max, total[:self.count_width])

        # Readout: address, read, capture (and clear), present
        read_index = Signal(self.bin_bits)
        read_last = Signal()
        read_addr = Signal()    # the readout sets the read address of its bank
        read_clear = Signal()   # the readout sets a clearing write of its bank

        if single:
            self._single_engine(m, valid2, bin2, bank2, bank_data, increment, initialising,
                                init_index, read_bank, read_index, read_addr, read_clear)
            # captured from the RAM output in CAPTURE (below)
            present_count = Signal(self.count_width, name="read_count")
        else:
            stored = self._dual_engine(m, valid2, bin2, bank2, banks, increment, read_bank,
                                       read_index, read_addr, read_clear)
            # The block RAM's output is slow: the readout takes the word where the pipeline
            # registers it. The bank being read out holds its output from CAPTURE until its
            # next read, which comes after PRESENT.
            present_count = Mux(read_bank, stored[1], stored[0])

        # After a swap, the events of the finished frame leave the pipeline within `latency`
        # cycles; the readout waits for them.
        drain = Signal(range(self.latency + 1))
        with m.If(swap):
            m.d.sync += drain.eq(self.latency)
        with m.Elif(drain != 0):
            m.d.sync += drain.eq(drain - 1)
        start_read = Signal()   # registered: a full bank, drained, and not just finished
        finishing = Signal()
        m.d.sync += start_read.eq(full.bit_select(read_bank, 1) & (drain == 0) & ~finishing)
        with m.FSM():
            with m.State("IDLE"):
                with m.If(start_read):
                    m.d.sync += read_index.eq(0)
                    m.next = "ADDRESS"
            with m.State("ADDRESS"):
                m.d.comb += read_addr.eq(1)
                m.d.sync += read_last.eq(read_index == bank_last[read_bank])
                m.next = "READ"
            with m.State("READ"):
                m.d.comb += read_clear.eq(1)
                m.next = "CAPTURE"
            with m.State("CAPTURE"):
                # the word read in READ (with single-port banks: never the output after a write)
                if single:
                    m.d.sync += present_count.eq(Mux(read_bank, bank_data[1], bank_data[0]))
                m.next = "PRESENT"
            with m.State("PRESENT"):
                m.d.comb += [
                    self.readout.valid.eq(1),
                    self.readout.payload.index.eq(read_index),
                    self.readout.payload.count.eq(present_count),
                    self.readout.payload.last.eq(read_last),
                ]
                with m.If(self.readout.ready):
                    with m.If(read_last):
                        m.d.comb += finishing.eq(1)
                        m.d.sync += full.bit_select(read_bank, 1).eq(0)
                        m.next = "IDLE"
                    with m.Else():
                        m.d.sync += read_index.eq(read_index + 1)
                        m.next = "ADDRESS"
        m.d.comb += [
            self.readout_shift.eq(bank_shift[read_bank]),
            self.pending.eq(full.bit_select(read_bank, 1)),
        ]

        return m

    def _dual_engine(self, m, valid2, bin2, bank2, banks, increment, read_bank, read_index,
                     read_addr, read_clear):
        # Stage R: the bin (fine shift) is registered here and in the read address register of
        # its bank: the block RAM samples it at the end of this cycle.
        valid_r = Signal()
        bin_r = Signal(self.bin_bits)
        bank_r = Signal()
        m.d.sync += [
            valid_r.eq(valid2),
            bin_r.eq(bin2),
            bank_r.eq(bank2),
        ]

        # A read misses the writes of the four events ahead of it (they are written in its own
        # cycle or later). Their bins are compared with its own in stage D, the outcome
        # registered for stage Q.
        valid_d, bin_d, bank_d = Signal(), Signal(self.bin_bits), Signal()
        valid_q, bin_q, bank_q = Signal(), Signal(self.bin_bits), Signal()
        valid_e, bin_e, bank_e = Signal(), Signal(self.bin_bits), Signal()
        valid_w, bin_w, bank_w = Signal(), Signal(self.bin_bits), Signal()
        valid_x, bin_x, bank_x = Signal(), Signal(self.bin_bits), Signal()  # written last cycle
        hit1_q = Signal()   # the event one ahead has the same bin
        hit2_q = Signal()   # ... two ahead
        hit3_q = Signal()   # ... three ahead
        hit4_q = Signal()   # ... four ahead
        def same(valid, bin, bank):
            return valid_d & valid & (bin_d == bin) & (bank_d == bank)
        m.d.sync += [
            valid_d.eq(valid_r),
            bin_d.eq(bin_r),
            bank_d.eq(bank_r),
            valid_q.eq(valid_d),
            bin_q.eq(bin_d),
            bank_q.eq(bank_d),
            hit1_q.eq(same(valid_q, bin_q, bank_q)),
            hit2_q.eq(same(valid_e, bin_e, bank_e)),
            hit3_q.eq(same(valid_w, bin_w, bank_w)),
            hit4_q.eq(same(valid_x, bin_x, bank_x)),
            valid_x.eq(valid_w),
            bin_x.eq(bin_w),
            bank_x.eq(bank_w),
        ]

        # Stage D: RAM data out, registered as it is (the block RAM's slow output drives nothing
        # else of the pipeline).
        # Stage Q: the registered RAM word. `written` holds the count of the event two ahead,
        # `written_before` that of the event three ahead, `written_before2` four ahead: on a
        # match they replace the stale RAM word.
        stored = [Signal(self.count_width, name=f"stored{k}") for k in range(2)]
        m.d.sync += [stored[k].eq(banks[k][0].data) for k in range(2)]
        written = Signal(self.count_width)
        written_before = Signal(self.count_width)
        written_before2 = Signal(self.count_width)
        base_e = Signal(self.count_width)
        hit1_e = Signal()
        m.d.sync += [
            valid_e.eq(valid_q),
            bin_e.eq(bin_q),
            bank_e.eq(bank_q),
            base_e.eq(Mux(hit2_q, written,
                          Mux(hit3_q, written_before,
                              Mux(hit4_q, written_before2,
                                  Mux(bank_q, stored[1], stored[0]))))),
            hit1_e.eq(hit1_q),
        ]

        # Stage E: increment, saturating. `written` now holds the count of the event one ahead.
        # Both candidates are incremented side by side and the forwarding choice comes last, so
        # the loop through `written` is one increment and one LUT.
        new = Signal(self.count_width)
        m.d.comb += new.eq(Mux(hit1_e, increment(written, "written"),
                               increment(base_e, "base")))
        m.d.sync += [
            written.eq(new),
            written_before.eq(written),
            written_before2.eq(written_before),
            valid_w.eq(valid_e),
            bin_w.eq(bin_e),
            bank_w.eq(bank_e),
        ]

        # Stage W: the RAM write, from registers (`written` is the data).

        # RAM ports, driven from registers: the pipeline uses the bank its event was tagged
        # with, the readout the other one.
        for k, (read_port, write_port) in enumerate(banks):
            read_address = Signal(self.bin_bits, name=f"read_address{k}")
            read_enable = Signal(name=f"read_enable{k}")
            write_address = Signal(self.bin_bits, name=f"write_address{k}")
            write_enable = Signal(name=f"write_enable{k}")
            write_zero = Signal(name=f"write_zero{k}")
            with m.If(valid2 & (bank2 == k)):
                m.d.sync += read_address.eq(bin2), read_enable.eq(1)
            with m.Elif(read_addr & (read_bank == k)):
                m.d.sync += read_address.eq(read_index), read_enable.eq(1)
            with m.Else():
                m.d.sync += read_enable.eq(0)
            with m.If(valid_e & (bank_e == k)):
                m.d.sync += write_address.eq(bin_e), write_enable.eq(1), write_zero.eq(0)
            with m.Elif(read_clear & (read_bank == k)):
                m.d.sync += write_address.eq(read_index), write_enable.eq(1), write_zero.eq(1)
            with m.Else():
                m.d.sync += write_enable.eq(0)
            m.d.comb += [
                read_port.addr.eq(read_address),
                read_port.en.eq(read_enable),
                write_port.addr.eq(write_address),
                write_port.en.eq(write_enable),
                write_port.data.eq(Mux(write_zero, 0, written)),
            ]

        return stored

    def _single_engine(self, m, valid2, bin2, bank2, bank_data, increment, initialising,
                       init_index, read_bank, read_index, read_addr, read_clear):
        # Accesses of a bank alternate: `read_slot` high means the access of the next cycle
        # (set up by the registers loaded at the end of this one) is a read slot.
        read_slot = Signal()
        m.d.sync += read_slot.eq(~read_slot)

        # Stage R: the bin (fine shift) is registered and held until a read slot: at most one
        # cycle, and the next event (two cycles behind) replaces it in the cycle it leaves.
        valid_r = Signal()
        bin_r = Signal(self.bin_bits)
        bank_r = Signal()
        issue = Signal()    # the read of the event in stage R is set up in this cycle
        m.d.comb += issue.eq(valid_r & read_slot)
        with m.If(valid2):
            m.d.sync += valid_r.eq(1), bin_r.eq(bin2), bank_r.eq(bank2)
        with m.Elif(read_slot):
            m.d.sync += valid_r.eq(0)

        # Stage A: the RAM reads the bin (cycle r). The event that read in cycle r - 2 is in
        # stage Q and writes in cycle r + 1: this read misses it. Events read at least two
        # cycles apart, so every other event ahead has written already. Compare the bins now.
        valid_a, bin_a, bank_a = Signal(), Signal(self.bin_bits), Signal()
        valid_d, bin_d, bank_d, hit_d = Signal(), Signal(self.bin_bits), Signal(), Signal()
        valid_q, bin_q, bank_q, hit_q = Signal(), Signal(self.bin_bits), Signal(), Signal()
        m.d.sync += [
            valid_a.eq(issue),
            bin_a.eq(bin_r),
            bank_a.eq(bank_r),
            valid_d.eq(valid_a),
            bin_d.eq(bin_a),
            bank_d.eq(bank_a),
            hit_d.eq(valid_a & valid_q & (bin_a == bin_q) & (bank_a == bank_q)),
        ]

        # Stage D: the RAM word is out (slowly, with SPRAM); register it.
        stored_q = Signal(self.count_width)
        m.d.sync += [
            stored_q.eq(Mux(bank_d, bank_data[1], bank_data[0])),
            valid_q.eq(valid_d),
            bin_q.eq(bin_d),
            bank_q.eq(bank_d),
            hit_q.eq(hit_d),
        ]

        # Stage Q: increment, saturating, and choose. `written` holds the count of the event
        # ahead (it changes only with an event in this stage) and `written_inc` that count plus
        # one, computed in the cycle between the two events: on a match it replaces the stale
        # word. The RAM word's increment saturates through its carry out, merged with the
        # choice: one carry chain and one LUT level to the data registers.
        written = Signal(self.count_width)
        written_inc = Signal(self.count_width)
        m.d.sync += written_inc.eq(increment(written, "written"))
        stored_total = Signal(self.count_width + 1)
        m.d.comb += stored_total.eq(stored_q + 1)
        new = Signal(self.count_width)
        m.d.comb += new.eq(Mux(hit_q, written_inc,
                               stored_total[:self.count_width] |
                               stored_total[-1].replicate(self.count_width)))
        with m.If(valid_q):
            m.d.sync += written.eq(new)

        # Stage W: the RAM write (cycle r + 3, a write slot).

        # RAM inputs, all registers: the initial clear, then the pipeline on the bank its event
        # was tagged with (writes and reads fall in different cycles), the readout on the other
        # bank (the pipeline has left it: the readout waits for the drain). The data registers
        # load 0 (clear) or the new count, nothing else: a register with a synchronous reset.
        for k, bank in enumerate(self.banks):
            address = Signal(self.bin_bits, name=f"address{k}")
            write = Signal(name=f"write{k}")
            data = Signal(self.count_width, name=f"data{k}")
            pipeline_write = valid_q & (bank_q == k)
            readout = (read_addr | read_clear) & (read_bank == k)
            with m.If(initialising):
                m.d.sync += address.eq(init_index), write.eq(1)
            with m.Elif(pipeline_write):
                m.d.sync += address.eq(bin_q), write.eq(1)
            with m.Elif(issue & (bank_r == k)):
                m.d.sync += address.eq(bin_r), write.eq(0)
            with m.Elif(readout):
                m.d.sync += address.eq(read_index), write.eq(read_clear)
            with m.Else():
                m.d.sync += write.eq(0)
            with m.If(initialising | (read_clear & (read_bank == k))):
                m.d.sync += data.eq(0)
            with m.Elif(pipeline_write):
                m.d.sync += data.eq(new)
            m.d.comb += [
                bank.addr.eq(address),
                bank.write_en.eq(write),
                bank.write_data.eq(data),
            ]
