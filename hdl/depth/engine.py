"""Depth engine: a DEPTH packet per frame from the histogram readout (``docs/depth.md``)."""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from .. import lookup
from .peak import MAX_FILTER, PeakFinder
from .record import QUOTIENT_BITS, RecordMaker
from ..event import ADDRESS_BITS, TIMESTAMP_BITS
from ..link.framing import PacketBeat
from ..packets.depth import DepthPacketizer
from ..histogram.layout import BIN_BITS, COUNT_WIDTH, MAX_SHIFT, readout_layout
from ..protocol import DepthHeader, DEPTH_PIXELS
from ..registers import DEPTH


__all__ = ["DepthSettings", "DepthEngine", "QUOTIENT_BITS"]


#: Settings of a :class:`DepthEngine`: ``filter`` (bins) and ``threshold`` (counts), the
#: layout of the register group :data:`~fliss.hdl.registers.DEPTH`.
DepthSettings = DEPTH.layout()

_PIXEL_BITS = (DEPTH_PIXELS - 1).bit_length()


class DepthEngine(wiring.Component):
    """Depth frames from a :class:`~fliss.hdl.histogram.engine.Histogram` readout.

    The readout of a frame is ``2**pixel_bits`` pixels of ``N = 2**(13 - shift)`` bins, in flat
    order (``index = pixel << (13 - shift) | bin``), ``last`` on the final bin. A
    :class:`~fliss.hdl.depth.peak.PeakFinder` takes one bin per cycle: box filter of
    ``W = min(filter, N)`` bins, the first largest window, its neighbours and the pixel's total.
    After each pixel's last bin the engine holds ``readout`` (``ready`` low) while a
    :class:`~fliss.hdl.depth.record.RecordMaker` works out the pixel's record (three serial
    divisions of :data:`QUOTIENT_BITS` cycles and ``W`` cycles of multiplication: about
    ``W + 67`` cycles with the pipeline) and a :class:`~fliss.hdl.packets.depth.DepthPacketizer`
    stores it; after the frame's last pixel the packetizer sends the DEPTH packet (a
    :class:`~fliss.hdl.protocol.DepthHeader`, then a :class:`~fliss.hdl.protocol.DepthRecord`
    per pixel) and only then does the engine take the next frame. The records are those of
    :func:`fliss.sim.models.depth.depth_frame`, bit for bit. ``shift``, ``pixel_bits``,
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
        Frames whose DEPTH packet has been started since reset (the next packet's ``frame``).
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
        m.submodules.maker = maker = RecordMaker()
        m.submodules.packetizer = packetizer = DepthPacketizer()
        wiring.connect(m, packetizer.packets, wiring.flipped(self.packets))

        readout = self.readout
        take = readout.valid & readout.ready
        mask = lookup([(1 << (TIMESTAMP_BITS - s)) - 1 for s in range(MAX_SHIFT + 1)],
                      self.shift, TIMESTAMP_BITS)
        bin = readout.p.index[:TIMESTAMP_BITS] & mask
        pixel_last = bin == mask

        # The frame's settings, sampled with its first bin; W = min(filter, N)
        header = Signal(DepthHeader)
        first_of_frame = Signal(init=1)
        bins = Signal(TIMESTAMP_BITS + 1)
        width = Signal(range(MAX_FILTER + 1))
        cap = lookup([min(MAX_FILTER, 1 << (TIMESTAMP_BITS - s)) for s in range(MAX_SHIFT + 1)],
                     self.shift, 5)
        filter = self.settings.filter
        width_now = Mux(filter > cap, cap, filter)
        with m.If(take & first_of_frame):
            m.d.sync += [
                header.frame.eq(self.frames),
                header.first_pixel.eq(self.first_pixel),
                header.pixel_bits.eq(self.pixel_bits),
                header.shift.eq(self.shift),
                header.filter.eq(filter),
                header.threshold.eq(self.settings.threshold),
                bins.eq(mask + 1),
                width.eq(width_now),
                first_of_frame.eq(0),
            ]
        with m.If(take & readout.p.last):
            m.d.sync += first_of_frame.eq(1)

        # Peak search, a bin per cycle
        m.d.comb += [
            peak.valid.eq(take),
            peak.count.eq(readout.p.count),
            peak.bin.eq(bin),
            peak.pixel_last.eq(pixel_last),
            peak.frame_last.eq(readout.p.last),
            peak.width.eq(width),               # (taken a cycle after the bin)
        ]

        # Each pixel's record, then the packet
        frame_last = Signal()
        m.d.comb += [
            maker.best.eq(peak.best),
            maker.best_bin.eq(peak.best_bin),
            maker.left.eq(peak.left),
            maker.right.eq(peak.right),
            maker.has_left.eq(peak.has_left),
            maker.has_right.eq(peak.has_right),
            maker.total.eq(peak.total),
            maker.width.eq(width),
            maker.bins.eq(bins),
            maker.threshold.eq(header.threshold),
            packetizer.record.eq(maker.record),
            packetizer.header.eq(header),
        ]
        with m.FSM():
            with m.State("RUN"):
                m.d.comb += readout.ready.eq(1)
                with m.If(take & pixel_last):
                    m.next = "SEARCH"

            with m.State("SEARCH"):
                with m.If(peak.done):
                    m.d.comb += maker.start.eq(1)
                    m.d.sync += frame_last.eq(peak.last)
                    m.next = "RECORD"

            with m.State("RECORD"):
                with m.If(maker.done):
                    m.d.comb += [packetizer.write.eq(1), packetizer.send.eq(frame_last)]
                    with m.If(frame_last):
                        m.d.sync += self.frames.eq(self.frames + 1)
                        m.next = "SEND"
                    with m.Else():
                        m.next = "RUN"

            with m.State("SEND"):
                with m.If(~packetizer.busy):
                    m.next = "RUN"

        return m
