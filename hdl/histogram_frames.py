"""Frames and banks of the histogram engine: which bank fills, for how long, with which settings."""

from amaranth.hdl import Array, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from .event import TIMESTAMP_BITS
from .histogram_layout import INTEGRATION_WIDTH, MAX_SHIFT
from .tdc import COUNTER_WIDTH


__all__ = ["FrameSequencer"]


class FrameSequencer(wiring.Component):
    """Frame timing and bank swaps of :class:`~fliss.hdl.histogram.Histogram`.

    One bank fills while the other is read out. A frame lasts ``integration`` cycles (sampled,
    with ``shift``, in the cycle before it starts); then the banks swap if the other bank is
    free, or the sequencer waits for it. ``enable`` falling ends the frame in progress. Each
    bank keeps the bin shift of its frame, the last bin of its readout and the mask of the
    timestamp bits that fall beyond the RAM (see :class:`~fliss.hdl.histogram.Histogram`).

    Parameters
    ----------
    bin_bits : int
        Width of the bin index.

    Members
    -------
    enable : In(1)
        Acquire frames.
    integration : In(32)
        Frame length in clock cycles.
    shift : In(range(14))
        Bin shift.
    hold : In(1)
        No frame starts (the banks are being cleared after reset).
    done : In(1)
        The readout transfers the last bin of the read bank: that bank is free from the next
        cycle.
    filling : Out(1)
        A frame is filling in this cycle.
    swap : Out(1)
        The frame ends in this cycle: the banks swap.
    fill_bank : Out(1)
        The bank that fills.
    fill_shift : Out(range(14))
        Bin shift of the fill bank's frame.
    fill_mask : Out(13)
        Timestamp bits that put a bin of the fill bank beyond the RAM.
    read_bank : Out(1)
        The other bank, read out.
    read_full : Out(1)
        The read bank holds a completed frame not yet entirely read out.
    read_shift : Out(range(14))
        Bin shift of the read bank's frame.
    read_last : Out(bin_bits)
        Last bin of the read bank's readout.
    frames : Out(32)
        Frames completed since reset; wraps around.
    """

    def __init__(self, bin_bits):
        self.bin_bits = bin_bits
        super().__init__({
            "enable":      In(1),
            "integration": In(INTEGRATION_WIDTH),
            "shift":       In(range(MAX_SHIFT + 1)),
            "hold":        In(1),
            "done":        In(1),
            "filling":     Out(1),
            "swap":        Out(1),
            "fill_bank":   Out(1),
            "fill_shift":  Out(range(MAX_SHIFT + 1)),
            "fill_mask":   Out(TIMESTAMP_BITS),
            "read_bank":   Out(1),
            "read_full":   Out(1),
            "read_shift":  Out(range(MAX_SHIFT + 1)),
            "read_last":   Out(bin_bits),
            "frames":      Out(COUNTER_WIDTH),
        })

    def elaborate(self, platform):
        m = Module()

        # Bank state: `fill_bank` fills, the other one is read out; `full[k]`: bank k holds a
        # completed frame that is not yet entirely read out and cleared.
        fill_bank = self.fill_bank
        read_bank = self.read_bank
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
        m.d.comb += [
            self.fill_shift.eq(bank_shift[fill_bank]),
            self.fill_mask.eq(bank_mask[fill_bank]),
            self.read_shift.eq(bank_shift[read_bank]),
            self.read_last.eq(bank_last[read_bank]),
            self.read_full.eq(full.bit_select(read_bank, 1)),
        ]

        remaining = Signal(INTEGRATION_WIDTH)   # cycles left in the frame, this one included
        final = Signal()                        # this is the last cycle of the frame
        swap = self.swap
        start_frame = Signal()
        new_bank = Signal()
        with m.If(swap):
            m.d.sync += [
                fill_bank.eq(~fill_bank),
                full.bit_select(fill_bank, 1).eq(1),
                self.frames.eq(self.frames + 1),
            ]
        with m.If(self.done):
            m.d.sync += full.bit_select(read_bank, 1).eq(0)
        m.d.comb += new_bank.eq(fill_bank ^ swap)
        with m.If(start_frame):
            m.d.sync += [
                remaining.eq(self.integration),
                final.eq(self.integration[1:] == 0),   # 0 or 1: a frame of one cycle
                bank_shift[new_bank].eq(self.shift),
                bank_last[new_bank].eq(last_for_shift),
                bank_mask[new_bank].eq(mask_for_shift),
            ]

        # Frame sequencer
        with m.FSM():
            with m.State("IDLE"):
                with m.If(self.enable & ~self.hold):
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

        return m
