"""The histogram side of :class:`fliss.hdl.top.FlissTop` without the histogram engine and the
UART, for cocotb: a readout stream in, framed bytes out (histogram packetizer, packet arbiter,
frame encoder, wired as in the top level)."""

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from ...hdl.link.arbiter import PacketArbiter
from ...hdl.event import ADDRESS_BITS
from ...hdl.link.framing import FrameEncoder
from ...hdl.histogram.layout import COUNT_WIDTH, MAX_SHIFT, readout_layout
from ...hdl.packets.histogram import HistogramPacketizer


__all__ = ["INDEX_BITS", "HistogramLinkTop"]


#: Width of the readout index: the largest bank split, 2**16 bins.
INDEX_BITS = 16


class HistogramLinkTop(wiring.Component):
    """Readout bins in, HISTOGRAM and HISTOGRAM_COMPACT frames out.

    Members
    -------
    readout : In(stream.Signature(readout_layout(16, COUNT_WIDTH)))
        Bins of the frames: flat index, count, last.
    shift, pixel_bits, first_pixel, full_readout : In
        Settings of the frame being read out, as :class:`HistogramPacketizer` takes them.
    tx : Out(stream.Signature(8))
        Frame bytes to the host.
    """

    readout:      In(stream.Signature(readout_layout(INDEX_BITS, COUNT_WIDTH)))
    shift:        In(range(MAX_SHIFT + 1))
    pixel_bits:   In(range(ADDRESS_BITS + 1))
    first_pixel:  In(ADDRESS_BITS)
    full_readout: In(1)
    tx:           Out(stream.Signature(8))

    def elaborate(self, platform):
        m = Module()
        m.submodules.packetizer = packetizer = HistogramPacketizer(index_bits=INDEX_BITS)
        m.submodules.arbiter = arbiter = PacketArbiter(1)
        m.submodules.encoder = encoder = FrameEncoder()
        wiring.connect(m, wiring.flipped(self.readout), packetizer.readout)
        wiring.connect(m, packetizer.packets, arbiter.i[0])
        wiring.connect(m, arbiter.o, encoder.i)
        wiring.connect(m, encoder.o, wiring.flipped(self.tx))
        m.d.comb += [
            packetizer.shift.eq(self.shift),
            packetizer.pixel_bits.eq(self.pixel_bits),
            packetizer.first_pixel.eq(self.first_pixel),
            packetizer.full_readout.eq(self.full_readout),
        ]
        return m
