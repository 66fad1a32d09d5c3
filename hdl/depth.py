"""Depth engine: a DEPTH packet per frame from the histogram readout (``docs/depth.md``)."""

from amaranth.hdl import Module, Mux, Signal, signed
from amaranth.lib import stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from . import lookup
from .depth_peak import PeakFinder, TOTAL_BITS, WINDOW_BITS
from .divider import SerialDivider
from .event import ADDRESS_BITS, TIMESTAMP_BITS
from .framing import PacketBeat
from .histogram_layout import BIN_BITS, COUNT_WIDTH, MAX_SHIFT, readout_layout
from .protocol import (PacketType, DepthHeader, DepthRecord, DEPTH_HEADER_BYTES,
                       DEPTH_RECORD_BYTES, DEPTH_PIXELS, DEPTH_FRACTION_BITS,
                       DEPTH_BACKGROUND_FRACTION_BITS)
from .registers import DEPTH


__all__ = ["DepthSettings", "DepthEngine", "QUOTIENT_BITS"]


#: Settings of a :class:`DepthEngine`: ``filter`` (bins) and ``threshold`` (counts), the
#: layout of the register group :data:`~fliss.hdl.registers.DEPTH`.
DepthSettings = DEPTH.layout()

#: Quotient bits of the engine's divisions: heights and backgrounds (in 1/16) are below 2**20.
QUOTIENT_BITS = WINDOW_BITS

_ONE = 1 << DEPTH_FRACTION_BITS
_PIXEL_BITS = (DEPTH_PIXELS - 1).bit_length()


class DepthEngine(wiring.Component):
    """Depth frames from a :class:`~fliss.hdl.histogram.Histogram` readout.

    The readout of a frame is ``2**pixel_bits`` pixels of ``N = 2**(13 - shift)`` bins, in flat
    order (``index = pixel << (13 - shift) | bin``), ``last`` on the final bin. A
    :class:`~fliss.hdl.depth_peak.PeakFinder` takes one bin per cycle: box filter of
    ``W = min(filter, N)`` bins, the first largest window, its neighbours and the pixel's total.
    After each pixel's last bin the engine holds ``readout`` (``ready`` low) while it works out
    the pixel's record with one :class:`~fliss.hdl.divider.SerialDivider` (three divisions of
    :data:`QUOTIENT_BITS` cycles and ``W`` cycles of multiplication, about ``W + 72`` cycles)
    and stores it; after the frame's last pixel it sends the DEPTH packet (a
    :class:`~fliss.hdl.protocol.DepthHeader`, then a :class:`~fliss.hdl.protocol.DepthRecord`
    per pixel) and only then takes the next frame. The records are those of
    :func:`fliss.sim.depth.depth_frame`, bit for bit. ``shift``, ``pixel_bits``,
    ``first_pixel`` and ``settings`` are sampled with the frame's first bin.

    Parameters
    ----------
    index_bits : int
        Width of the readout's ``index`` (the histogram bank's address bits).

    Members
    -------
    readout : In(stream.Signature(readout_layout(index_bits, 16)))
        Bins of the frames: ``index``, ``count``, ``last``.
    shift : In(range(14))
    pixel_bits : In(range(7))
    first_pixel : In(6)
        Bin shift, pixels and first pixel's address of the frame being read out.
    settings : In(DepthSettings)
        ``filter`` (1 to 16 bins) and ``threshold`` (counts).
    packets : Out(stream.Signature(PacketBeat))
        One DEPTH packet per frame.
    frames : Out(32)
        DEPTH packets sent since reset (the next packet's ``frame``).
    """

    def __init__(self, *, index_bits=BIN_BITS):
        if not isinstance(index_bits, int) or not TIMESTAMP_BITS <= index_bits <= 32:
            raise ValueError(f"Index width must be an integer from {TIMESTAMP_BITS} to 32 bits, "
                             f"not {index_bits!r}")
        self.index_bits = index_bits
        super().__init__({
            "readout":     In(stream.Signature(readout_layout(index_bits, COUNT_WIDTH))),
            "shift":       In(range(MAX_SHIFT + 1)),
            "pixel_bits":  In(range(_PIXEL_BITS + 1)),
            "first_pixel": In(ADDRESS_BITS),
            "settings":    In(DepthSettings),
            "packets":     Out(stream.Signature(PacketBeat)),
            "frames":      Out(32),
        })

    def elaborate(self, platform):
        m = Module()

        m.submodules.peak = peak = PeakFinder()
        m.submodules.divider = divider = SerialDivider(TOTAL_BITS + 4, WINDOW_BITS + 1,
                                                       QUOTIENT_BITS)
        m.submodules.records = records = Memory(shape=DepthRecord, depth=DEPTH_PIXELS, init=[])
        write = records.write_port()
        read = records.read_port()

        readout = self.readout
        take = readout.valid & readout.ready
        mask = lookup([(1 << (TIMESTAMP_BITS - s)) - 1 for s in range(MAX_SHIFT + 1)],
                      self.shift, TIMESTAMP_BITS)
        bin = readout.p.index[:TIMESTAMP_BITS] & mask
        pixel_last = bin == mask

        # The frame's settings, sampled with its first bin
        header = Signal(DepthHeader)
        first_of_frame = Signal(init=1)
        bins = Signal(TIMESTAMP_BITS + 1)           # N
        width = Signal(range(17))                   # W = min(filter, N)
        threshold = Signal(16)
        cap = lookup([min(16, 1 << (TIMESTAMP_BITS - s)) for s in range(MAX_SHIFT + 1)],
                     self.shift, 5)
        with m.If(take & first_of_frame):
            m.d.sync += [
                header.frame.eq(self.frames),
                header.first_pixel.eq(self.first_pixel),
                header.pixel_bits.eq(self.pixel_bits),
                header.shift.eq(self.shift),
                header.filter.eq(self.settings.filter),
                header.threshold.eq(self.settings.threshold),
                threshold.eq(self.settings.threshold),
                bins.eq(mask + 1),
                width.eq(Mux(self.settings.filter > cap, cap, self.settings.filter)),
                first_of_frame.eq(0),
            ]
        with m.If(take & readout.p.last):
            m.d.sync += first_of_frame.eq(1)

        # Peak search, one bin per cycle
        m.d.comb += [
            peak.valid.eq(take),
            peak.count.eq(readout.p.count),
            peak.bin.eq(bin),
            peak.pixel_last.eq(pixel_last),
            peak.frame_last.eq(readout.p.last),
            peak.width.eq(Mux(first_of_frame, Mux(self.settings.filter > cap, cap,
                                                   self.settings.filter), width)),
        ]

        # The pixel's record: background R / D, height F - ceil(W R / D), position
        rest = Signal(TOTAL_BITS)                   # R = S - F
        spare = Signal(TIMESTAMP_BITS + 1)          # D = N - W
        product = Signal(TOTAL_BITS + 4)            # W R
        steps = Signal(range(17))
        record = Signal(DepthRecord)
        frame_last = Signal()
        pixel = Signal(range(DEPTH_PIXELS + 1))
        a = Signal(WINDOW_BITS)                     # F - f[k - 1]
        b = Signal(WINDOW_BITS)                     # F - f[k + 1]
        interpolate = Signal()
        height = Signal(signed(WINDOW_BITS + 2))

        # Sending: the header, then the records
        byte = Signal(range(max(DEPTH_HEADER_BYTES, DEPTH_RECORD_BYTES)))
        word = Signal(DEPTH_RECORD_BYTES * 8)
        pixels = lookup([1 << p for p in range(_PIXEL_BITS + 1)], header.pixel_bits)
        length = lookup([DEPTH_HEADER_BYTES + (1 << p) * DEPTH_RECORD_BYTES
                         for p in range(_PIXEL_BITS + 1)], header.pixel_bits, 16)
        m.d.comb += [
            self.packets.p.header.type.eq(PacketType.DEPTH),
            self.packets.p.header.length.eq(length),
            read.addr.eq(pixel),
            write.addr.eq(pixel),
            write.data.eq(record),
        ]

        with m.FSM():
            with m.State("RUN"):
                m.d.comb += readout.ready.eq(1)
                with m.If(take & pixel_last):
                    m.next = "DRAIN"

            with m.State("DRAIN"):
                with m.If(peak.done):
                    m.d.sync += [
                        rest.eq(peak.total - peak.best),
                        spare.eq(bins - width),
                        product.eq(0),
                        steps.eq(width),
                        frame_last.eq(peak.last),
                        a.eq(peak.best - peak.left),
                        b.eq(peak.best - peak.right),
                        interpolate.eq(peak.has_left & peak.has_right),
                    ]
                    m.next = "MULTIPLY"

            with m.State("MULTIPLY"):
                m.d.sync += [product.eq(product + rest), steps.eq(steps - 1)]
                with m.If(steps == 1):
                    m.next = "HEIGHT"

            with m.State("HEIGHT"):
                with m.If(~divider.busy):
                    m.d.comb += [divider.start.eq(1), divider.dividend.eq(product),
                                 divider.divisor.eq(spare)]
                    m.next = "BACKGROUND"

            with m.State("BACKGROUND"):
                with m.If(~divider.busy):
                    up = divider.remainder != 0
                    m.d.sync += height.eq(Mux(spare == 0, peak.best,
                                              peak.best - divider.quotient - up))
                    m.d.comb += [divider.start.eq(1),
                                 divider.dividend.eq(rest << DEPTH_BACKGROUND_FRACTION_BITS),
                                 divider.divisor.eq(spare)]
                    m.next = "STEP"

            with m.State("STEP"):
                with m.If(~divider.busy):
                    top = (1 << len(record.background)) - 1
                    m.d.sync += [
                        record.background.eq(Mux(spare == 0, 0,
                                                 Mux(divider.quotient > top, top,
                                                     divider.quotient))),
                        record.height.eq(Mux(height < 0, 0, height)),
                        record.detected.eq((height >= 0) & (height >= threshold)),
                    ]
                    m.d.comb += [divider.start.eq(1),
                                 divider.dividend.eq(Mux(a > b, a - b, b - a) << 3),
                                 divider.divisor.eq(a + b)]
                    m.next = "POSITION"

            with m.State("POSITION"):
                with m.If(~divider.busy):
                    step = Mux(interpolate, Mux(a > b, divider.quotient, -divider.quotient), 0)
                    centre = ((peak.best_bin + 1) << DEPTH_FRACTION_BITS) - \
                        (width << (DEPTH_FRACTION_BITS - 1))
                    m.d.sync += record.position.eq(centre + step)
                    m.next = "STORE"

            with m.State("STORE"):
                m.d.comb += write.en.eq(1)
                m.d.sync += pixel.eq(pixel + 1)
                with m.If(frame_last):
                    m.next = "HEADER"
                with m.Else():
                    m.next = "RUN"

            with m.State("HEADER"):
                m.d.comb += [self.packets.valid.eq(1), self.packets.p.first.eq(1)]
                with m.If(self.packets.ready):
                    m.d.sync += [byte.eq(0), pixel.eq(0)]
                    m.next = "PREFIX"

            with m.State("PREFIX"):
                m.d.comb += [self.packets.valid.eq(1),
                             self.packets.p.data.eq(header.as_value().word_select(byte, 8))]
                with m.If(self.packets.ready):
                    m.d.sync += byte.eq(byte + 1)
                    with m.If(byte == DEPTH_HEADER_BYTES - 1):
                        m.d.sync += byte.eq(0)
                        m.next = "FETCH"

            with m.State("FETCH"):
                m.next = "LOAD"

            with m.State("LOAD"):
                m.d.sync += word.eq(read.data.as_value())
                m.next = "RECORD"

            with m.State("RECORD"):
                final = (byte == DEPTH_RECORD_BYTES - 1) & (pixel == pixels - 1)
                m.d.comb += [self.packets.valid.eq(1),
                             self.packets.p.data.eq(word[:8]),
                             self.packets.p.last.eq(final)]
                with m.If(self.packets.ready):
                    m.d.sync += [byte.eq(byte + 1), word.eq(word >> 8)]
                    with m.If(byte == DEPTH_RECORD_BYTES - 1):
                        m.d.sync += [byte.eq(0), pixel.eq(pixel + 1)]
                        m.next = "FETCH"
                    with m.If(final):
                        m.d.sync += [pixel.eq(0), self.frames.eq(self.frames + 1)]
                        m.next = "RUN"

        return m
