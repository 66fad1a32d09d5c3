"""Frames and banks of the histogram engine: which bank fills, for how long, with which settings."""

from amaranth.hdl import Array, Cat, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from .. import lookup
from ..event import TIMESTAMP_BITS
from .layout import INTEGRATION_WIDTH, MAX_SHIFT, PIXEL_BITS, PIXEL_SETTING_BITS
from ..tdc import COUNTER_WIDTH


__all__ = ["FrameSequencer"]


class FrameSequencer(wiring.Component):
    """Frame timing and bank swaps of :class:`~fliss.hdl.histogram.engine.Histogram`.

    One bank fills while the other is read out. A frame lasts ``integration`` cycles (sampled,
    with ``shift``, ``pixel_bits`` and ``first_pixel``, in the cycle before it starts); then the
    banks swap if the other bank is free, or the sequencer waits for it. ``enable`` falling ends
    the frame in progress. Each bank keeps the split of its frame: ``2**q`` pixels (``q =
    min(pixel_bits, bank_bits)``) of ``2**b`` bins, ``b = min(13 - shift, bank_bits - q)`` (so
    ``b = 13 - shift`` when the split fits the bank), the last flat index of its readout, the
    mask of the timestamp bits that put a bin beyond ``2**b - 1`` and that of the pixel offsets
    within the frame (see :class:`~fliss.hdl.histogram.engine.Histogram`).

    Parameters
    ----------
    bank_bits : int
        Width of a bank's word address.

    Members
    -------
    enable : In(1)
        Acquire frames.
    integration : In(32)
        Frame length in clock cycles.
    shift : In(range(14))
        Bin shift.
    pixel_bits : In(3)
        A frame holds ``2**pixel_bits`` pixels.
    first_pixel : In(6)
        Address of the frame's first pixel.
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
        Timestamp bits that put a bin of the fill bank beyond its pixel's bins.
    fill_first : Out(6)
        First pixel address of the fill bank's frame.
    fill_pixels : Out(6)
        Pixel offset bits beyond the fill bank's frame (``63 & ~(2**q - 1)``).
    fill_position : Out(range(14))
        ``b`` of the fill bank's frame: a pixel's bins start at ``pixel << b``.
    read_bank : Out(1)
        The other bank, read out.
    read_full : Out(1)
        The read bank holds a completed frame not yet entirely read out.
    read_shift : Out(range(14))
        Bin shift of the read bank's frame.
    read_pixel_bits : Out(3)
        ``q`` of the read bank's frame.
    read_first : Out(6)
        First pixel address of the read bank's frame.
    read_last : Out(bank_bits)
        Last flat index of the read bank's readout.
    frames : Out(32)
        Frames completed since reset; wraps around.
    """

    def __init__(self, bank_bits):
        self.bank_bits = bank_bits
        super().__init__({
            "enable":          In(1),
            "integration":     In(INTEGRATION_WIDTH),
            "shift":           In(range(MAX_SHIFT + 1)),
            "pixel_bits":      In(PIXEL_SETTING_BITS),
            "first_pixel":     In(PIXEL_BITS),
            "hold":            In(1),
            "done":            In(1),
            "filling":         Out(1),
            "swap":            Out(1),
            "fill_bank":       Out(1),
            "fill_shift":      Out(range(MAX_SHIFT + 1)),
            "fill_mask":       Out(TIMESTAMP_BITS),
            "fill_first":      Out(PIXEL_BITS),
            "fill_pixels":     Out(PIXEL_BITS),
            "fill_position":   Out(range(TIMESTAMP_BITS + 1)),
            "read_bank":       Out(1),
            "read_full":       Out(1),
            "read_shift":      Out(range(MAX_SHIFT + 1)),
            "read_pixel_bits": Out(PIXEL_SETTING_BITS),
            "read_first":      Out(PIXEL_BITS),
            "read_last":       Out(bank_bits),
            "frames":          Out(COUNTER_WIDTH),
        })

    def split(self, shift, pixel_bits):
        """``(q, b)`` of a frame: ``2**q`` pixels of ``2**b`` bins."""
        q = min(pixel_bits, self.bank_bits)
        return q, min(TIMESTAMP_BITS - shift, self.bank_bits - q)

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

        # Per-bank settings, sampled when a frame starts in that bank: the split's constants
        # come out of a table indexed by shift and pixel bits (nothing on the events' path).
        fields = {
            "shift":    range(MAX_SHIFT + 1),
            "q":        PIXEL_SETTING_BITS,
            "first":    PIXEL_BITS,
            "last":     self.bank_bits,
            "mask":     TIMESTAMP_BITS,
            "pixels":   PIXEL_BITS,
            "position": range(TIMESTAMP_BITS + 1),
        }
        bank = {name: Array(Signal(shape, name=f"bank{k}_{name}") for k in range(2))
                for name, shape in fields.items()}
        new = {name: Signal(shape, name=f"new_{name}") for name, shape in fields.items()}
        m.d.comb += [new["shift"].eq(self.shift), new["first"].eq(self.first_pixel)]
        index = Cat(self.shift, self.pixel_bits)
        splits = [self.split(shift, pixel_bits) if shift <= MAX_SHIFT else None
                  for pixel_bits in range(1 << PIXEL_SETTING_BITS)
                  for shift in range(1 << len(self.shift))]
        tables = {
            "q":        lambda shift, q, b: q,
            "last":     lambda shift, q, b: (1 << (q + b)) - 1,
            "mask":     lambda shift, q, b: ((1 << TIMESTAMP_BITS) - 1) & ~((1 << (b + shift)) - 1),
            "pixels":   lambda shift, q, b: ((1 << PIXEL_BITS) - 1) & ~((1 << q) - 1),
            "position": lambda shift, q, b: b,
        }
        for name, value in tables.items():
            entries = [0 if split is None else value(n % (1 << len(self.shift)), *split)
                       for n, split in enumerate(splits)]
            m.d.comb += new[name].eq(lookup(entries, index, len(new[name]), rom=True))
        m.d.comb += [
            self.fill_shift.eq(bank["shift"][fill_bank]),
            self.fill_mask.eq(bank["mask"][fill_bank]),
            self.fill_first.eq(bank["first"][fill_bank]),
            self.fill_pixels.eq(bank["pixels"][fill_bank]),
            self.fill_position.eq(bank["position"][fill_bank]),
            self.read_shift.eq(bank["shift"][read_bank]),
            self.read_pixel_bits.eq(bank["q"][read_bank]),
            self.read_first.eq(bank["first"][read_bank]),
            self.read_last.eq(bank["last"][read_bank]),
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
                *(bank[name][new_bank].eq(new[name]) for name in fields),
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
