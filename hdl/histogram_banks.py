"""Bank storage of the histogram engine: two banks of RAM and the pipeline that counts events.

:class:`DualPortBanks` keeps the banks in block RAM with a read and a write port and counts an
event in every cycle; :class:`SinglePortBanks` keeps them in single-port RAM (iCE40 SPRAM) and
counts an event at most every other cycle. Both present the same ports to
:class:`~fliss.hdl.histogram.Histogram`.
"""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from .spram import SinglePortRam


__all__ = ["LATENCY", "SINGLE_LATENCY", "DualPortBanks", "SinglePortBanks"]


#: Cycles from an event's transfer on ``events`` to the block RAM write of its bin
#: (``ram="dual"``).
LATENCY = 7
#: Most cycles from an event's transfer on ``events`` to the RAM write of its bin, with
#: ``ram="single"``.
SINGLE_LATENCY = 8


def _increment(m, value, width, name):
    # `value + 1`, saturating at all ones
    total = Signal(width + 1, name=f"{name}_total")
    m.d.comb += total.eq(value + 1)
    return Mux(total[-1], (1 << width) - 1, total[:width])


def _members(bank_bits, count_width, *, initialising):
    return {
        "valid":         In(1),
        "bin":           In(bank_bits),
        "bank":          In(1),
        "readout_bank":  In(1),
        "readout_index": In(bank_bits),
        "readout_read":  In(1),
        "readout_clear": In(1),
        "word":          Out(count_width),
        "initialising":  Out(1, init=int(initialising)),
    }


_MEMBERS_DOC = """
    Parameters
    ----------
    bank_bits : int
        Width of a bank's word address: ``2**bank_bits`` bins per bank.
    count_width : int
        Width of a bin count.

    Members
    -------
    valid : In(1)
        An event's bin is in ``bin`` (the histogram's stage 2).
    bin : In(bank_bits)
        Its flat bin index (``pixel << b | bin``).
    bank : In(1)
        The bank it counts in.
    readout_bank : In(1)
        The bank being read out.
    readout_index : In(bank_bits)
        The bin the readout reads or clears.
    readout_read : In(1)
        The readout reads ``readout_index`` (set up in this cycle).
    readout_clear : In(1)
        The readout clears ``readout_index`` (set up in this cycle).
    word : Out(count_width)
        The readout bank's word of the bin read.
    initialising : Out(1)
        The banks are being cleared after reset.

    Attributes
    ----------
    banks : tuple of two RAMs
        Storage of the two banks.
    latency : int
        Most cycles from an event's arrival to the RAM write of its bin.
    init_cycles : int
        Cycles after reset before the banks may be used.
"""


class DualPortBanks(wiring.Component):
    __doc__ = """Two banks in block RAM (:class:`amaranth.lib.memory.Memory`), one event per cycle.

    The pipeline from the bin on: register the read address (R), RAM data out (D), RAM word
    registered (Q), saturating increment with forwarding from the four events ahead (E), RAM
    write (W). ``word`` is the registered RAM word of the readout bank; it holds from the
    readout's CAPTURE until its next read.
""" + _MEMBERS_DOC

    def __init__(self, bank_bits, count_width):
        self.bank_bits = bank_bits
        self.count_width = count_width
        self.latency = LATENCY
        self.init_cycles = 0
        super().__init__(_members(bank_bits, count_width, initialising=False))
        self.banks = tuple(Memory(shape=count_width, depth=1 << bank_bits, init=[])
                           for _ in range(2))

    def elaborate(self, platform):
        m = Module()

        for k, bank in enumerate(self.banks):
            m.submodules[f"bank{k}"] = bank
        ports = [(memory.read_port(), memory.write_port()) for memory in self.banks]

        # Stage R: the bin (fine shift) is registered here and in the read address register of
        # its bank: the block RAM samples it at the end of this cycle.
        valid_r = Signal()
        bin_r = Signal(self.bank_bits)
        bank_r = Signal()
        m.d.sync += [
            valid_r.eq(self.valid),
            bin_r.eq(self.bin),
            bank_r.eq(self.bank),
        ]

        # A read misses the writes of the four events ahead of it (they are written in its own
        # cycle or later). Their bins are compared with its own in stage D, the outcome
        # registered for stage Q.
        valid_d, bin_d, bank_d = Signal(), Signal(self.bank_bits), Signal()
        valid_q, bin_q, bank_q = Signal(), Signal(self.bank_bits), Signal()
        valid_e, bin_e, bank_e = Signal(), Signal(self.bank_bits), Signal()
        valid_w, bin_w, bank_w = Signal(), Signal(self.bank_bits), Signal()
        valid_x, bin_x, bank_x = Signal(), Signal(self.bank_bits), Signal()  # written last cycle
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
        m.d.sync += [stored[k].eq(ports[k][0].data) for k in range(2)]
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
        m.d.comb += new.eq(Mux(hit1_e, _increment(m, written, self.count_width, "written"),
                               _increment(m, base_e, self.count_width, "base")))
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
        for k, (read_port, write_port) in enumerate(ports):
            read_address = Signal(self.bank_bits, name=f"read_address{k}")
            read_enable = Signal(name=f"read_enable{k}")
            write_address = Signal(self.bank_bits, name=f"write_address{k}")
            write_enable = Signal(name=f"write_enable{k}")
            write_zero = Signal(name=f"write_zero{k}")
            with m.If(self.valid & (self.bank == k)):
                m.d.sync += read_address.eq(self.bin), read_enable.eq(1)
            with m.Elif(self.readout_read & (self.readout_bank == k)):
                m.d.sync += read_address.eq(self.readout_index), read_enable.eq(1)
            with m.Else():
                m.d.sync += read_enable.eq(0)
            with m.If(valid_e & (bank_e == k)):
                m.d.sync += write_address.eq(bin_e), write_enable.eq(1), write_zero.eq(0)
            with m.Elif(self.readout_clear & (self.readout_bank == k)):
                m.d.sync += [write_address.eq(self.readout_index), write_enable.eq(1),
                             write_zero.eq(1)]
            with m.Else():
                m.d.sync += write_enable.eq(0)
            m.d.comb += [
                read_port.addr.eq(read_address),
                read_port.en.eq(read_enable),
                write_port.addr.eq(write_address),
                write_port.en.eq(write_enable),
                write_port.data.eq(Mux(write_zero, 0, written)),
            ]

        # The block RAM's output is slow: the readout takes the word where the pipeline
        # registers it.
        m.d.comb += self.word.eq(Mux(self.readout_bank, stored[1], stored[0]))

        return m


class SinglePortBanks(wiring.Component):
    __doc__ = """Two banks in single-port RAM (:class:`~fliss.hdl.spram.SinglePortRam`), an event
    at most every other cycle.

    Accesses alternate between read slots and write slots. The bin waits for a read slot (R),
    the RAM reads it (A), its word comes out (D) and is registered (Q), incremented (saturating,
    with forwarding from the event ahead) and written back (W). After reset both banks are
    cleared, ``2**bank_bits`` cycles, while ``initialising`` is high. ``word`` is the readout
    bank's RAM output.
""" + _MEMBERS_DOC

    def __init__(self, bank_bits, count_width):
        self.bank_bits = bank_bits
        self.count_width = count_width
        self.latency = SINGLE_LATENCY
        self.init_cycles = 1 << bank_bits
        super().__init__(_members(bank_bits, count_width, initialising=True))
        self.banks = tuple(SinglePortRam(depth=1 << bank_bits, width=count_width)
                           for _ in range(2))

    def elaborate(self, platform):
        m = Module()

        for k, bank in enumerate(self.banks):
            m.submodules[f"bank{k}"] = bank
        bank_data = [bank.read_data for bank in self.banks]

        # Single-port banks start undefined: clear both after reset, before the first frame.
        initialising = self.initialising
        init_index = Signal(self.bank_bits)
        with m.If(initialising):
            m.d.sync += init_index.eq(init_index + 1)
            with m.If(init_index == (1 << self.bank_bits) - 1):
                m.d.sync += initialising.eq(0)

        # Accesses of a bank alternate: `read_slot` high means the access of the next cycle
        # (set up by the registers loaded at the end of this one) is a read slot.
        read_slot = Signal()
        m.d.sync += read_slot.eq(~read_slot)

        # Stage R: the bin (fine shift) is registered and held until a read slot: at most one
        # cycle, and the next event (two cycles behind) replaces it in the cycle it leaves.
        valid_r = Signal()
        bin_r = Signal(self.bank_bits)
        bank_r = Signal()
        issue = Signal()    # the read of the event in stage R is set up in this cycle
        m.d.comb += issue.eq(valid_r & read_slot)
        with m.If(self.valid):
            m.d.sync += valid_r.eq(1), bin_r.eq(self.bin), bank_r.eq(self.bank)
        with m.Elif(read_slot):
            m.d.sync += valid_r.eq(0)

        # Stage A: the RAM reads the bin (cycle r). The event that read in cycle r - 2 is in
        # stage Q and writes in cycle r + 1: this read misses it. Events read at least two
        # cycles apart, so every other event ahead has written already. Compare the bins now.
        valid_a, bin_a, bank_a = Signal(), Signal(self.bank_bits), Signal()
        valid_d, bin_d, bank_d, hit_d = Signal(), Signal(self.bank_bits), Signal(), Signal()
        valid_q, bin_q, bank_q, hit_q = Signal(), Signal(self.bank_bits), Signal(), Signal()
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
        m.d.sync += written_inc.eq(_increment(m, written, self.count_width, "written"))
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
            address = Signal(self.bank_bits, name=f"address{k}")
            write = Signal(name=f"write{k}")
            data = Signal(self.count_width, name=f"data{k}")
            pipeline_write = valid_q & (bank_q == k)
            readout = (self.readout_read | self.readout_clear) & (self.readout_bank == k)
            with m.If(initialising):
                m.d.sync += address.eq(init_index), write.eq(1)
            with m.Elif(pipeline_write):
                m.d.sync += address.eq(bin_q), write.eq(1)
            with m.Elif(issue & (bank_r == k)):
                m.d.sync += address.eq(bin_r), write.eq(0)
            with m.Elif(readout):
                m.d.sync += address.eq(self.readout_index), write.eq(self.readout_clear)
            with m.Else():
                m.d.sync += write.eq(0)
            with m.If(initialising | (self.readout_clear & (self.readout_bank == k))):
                m.d.sync += data.eq(0)
            with m.Elif(pipeline_write):
                m.d.sync += data.eq(new)
            m.d.comb += [
                bank.addr.eq(address),
                bank.write_en.eq(write),
                bank.write_data.eq(data),
            ]

        m.d.comb += self.word.eq(Mux(self.readout_bank, bank_data[1], bank_data[0]))

        return m
