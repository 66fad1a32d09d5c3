"""Readout of the histogram engine: a full bank, bin after bin, cleared as it goes."""

from amaranth.hdl import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from .dual import READ_STAGES
from .layout import readout_layout


__all__ = ["SETTLE", "READOUT_CYCLES_PER_BIN", "readout_cycles_per_bin", "BankReadout"]


def readout_cycles_per_bin(settle):
    """Clock cycles per bin on ``readout`` when its consumer is always ready, the word coming
    ``settle`` cycles after the first of CAPTURE (:class:`BankReadout`): ADDRESS, READ,
    CAPTURE (``settle`` + 1) and PRESENT."""
    return 4 + settle


#: Most cycles the readout waits after a read for the word (the dual-port banks' read stages;
#: ``settle``).
SETTLE = READ_STAGES
#: Most clock cycles per bin on ``readout`` when its consumer is always ready
#: (:func:`readout_cycles_per_bin` of :data:`SETTLE`).
READOUT_CYCLES_PER_BIN = readout_cycles_per_bin(SETTLE)


class BankReadout(wiring.Component):
    """Reads the full bank of :class:`~fliss.hdl.histogram.engine.Histogram` out in flat index order
    (pixel after pixel, bin after bin), up to the frame's ``last`` index.

    After a swap it waits ``latency`` cycles for the last events of the frame to leave the
    pipeline, then for each bin sets the bank's read address (ADDRESS), sets a clearing write
    (READ), takes the word (CAPTURE, ``settle`` + 1 cycles: the dual-port banks' word comes
    through their read stages) and presents it on ``readout`` (PRESENT) until transferred:
    :func:`readout_cycles_per_bin` cycles per bin.

    Parameters
    ----------
    bank_bits : int
        Width of a bank's word address (the flat index).
    count_width : int
        Width of a bin count.
    latency : int
        Most cycles from an event's arrival to the RAM write of its bin.
    capture : bool
        Register ``word`` in the first cycle of CAPTURE (single-port banks, whose output after a
        write cycle is not the word read); otherwise ``word`` holds from the last cycle of
        CAPTURE until the next read of the bank.
    settle : int
        Cycles the word takes after the first of CAPTURE: the banks' ``read_stages``.

    Members
    -------
    swap : In(1)
        The banks swap in this cycle.
    full : In(1)
        The read bank holds a completed frame.
    last : In(bank_bits)
        Last flat index of the read bank's readout.
    word : In(count_width)
        The word the read bank gives for the bin read.
    index : Out(bank_bits)
        Flat index being read out.
    address : Out(1)
        The read bank reads ``index`` (set up in this cycle).
    clear : Out(1)
        The read bank writes zero to ``index`` (set up in this cycle).
    done : Out(1)
        The last bin is transferred: the read bank is free.
    readout : Out(stream.Signature(readout_layout(bank_bits, count_width)))
        Bins of the frame: ``index``, ``count``, ``last``.
    """

    def __init__(self, bank_bits, count_width, *, latency, capture, settle):
        self.latency = latency
        self.settle = settle
        self.capture = capture
        super().__init__({
            "swap":    In(1),
            "full":    In(1),
            "last":    In(bank_bits),
            "word":    In(count_width),
            "index":   Out(bank_bits),
            "address": Out(1),
            "clear":   Out(1),
            "done":    Out(1),
            "readout": Out(stream.Signature(readout_layout(bank_bits, count_width))),
        })

    def elaborate(self, platform):
        m = Module()

        read_index = self.index
        read_last = Signal()
        settle = Signal(range(self.settle + 1))
        if self.capture:
            present_count = Signal.like(self.word, name="read_count")
        else:
            present_count = self.word

        # After a swap, the events of the finished frame leave the pipeline within `latency`
        # cycles; the readout waits for them.
        drain = Signal(range(self.latency + 1))
        with m.If(self.swap):
            m.d.sync += drain.eq(self.latency)
        with m.Elif(drain != 0):
            m.d.sync += drain.eq(drain - 1)
        start_read = Signal()   # registered: a full bank, drained, and not just finished
        m.d.sync += start_read.eq(self.full & (drain == 0) & ~self.done)
        with m.FSM():
            with m.State("IDLE"):
                with m.If(start_read):
                    m.d.sync += read_index.eq(0)
                    m.next = "ADDRESS"
            with m.State("ADDRESS"):
                m.d.comb += self.address.eq(1)
                m.d.sync += read_last.eq(read_index == self.last)
                m.next = "READ"
            with m.State("READ"):
                m.d.comb += self.clear.eq(1)
                m.next = "CAPTURE"
            with m.State("CAPTURE"):
                # the word read in READ (with single-port banks: never the output after a
                # write), then `settle` cycles more (with dual-port banks: the word on its way)
                if self.capture:
                    with m.If(settle == 0):
                        m.d.sync += present_count.eq(self.word)
                m.d.sync += settle.eq(settle + 1)
                with m.If(settle >= self.settle):
                    m.d.sync += settle.eq(0)
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
                        m.d.comb += self.done.eq(1)
                        m.next = "IDLE"
                    with m.Else():
                        m.d.sync += read_index.eq(read_index + 1)
                        m.next = "ADDRESS"

        return m
