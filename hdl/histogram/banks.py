"""Bank storage of the histogram engine: two banks of RAM and the pipeline that counts events.

:class:`~fliss.hdl.histogram.dual.DualPortBanks` keeps the banks in block RAM with a read and a
write port and counts an event in every cycle; :class:`SinglePortBanks` keeps them in single-port
RAM (iCE40 SPRAM) and counts an event at most every other cycle. Both present the same ports to
:class:`~fliss.hdl.histogram.engine.Histogram`.
"""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from ..spram import SinglePortRam


__all__ = ["SINGLE_LATENCY", "SinglePortBanks"]


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
        self.read_stages = 0
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
