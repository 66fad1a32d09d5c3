"""HISTOGRAM packets only (full chunks), from a histogram readout: the histogram packetizer of
the smallest builds."""

from amaranth.hdl import Module, Signal
from amaranth.lib import wiring

from .. import lookup
from ..event import TIMESTAMP_BITS
from ..histogram.chunk import CHUNK_HEADER_BYTES, COUNT_BYTES, ChunkEmitter
from ..histogram.layout import BIN_BITS
from .histogram import histogram_packetizer_members
from ..protocol import CHUNK_BINS, MAX_FRAME_BITS


__all__ = ["FullHistogramPacketizer"]


class FullHistogramPacketizer(wiring.Component):
    """HISTOGRAM packets only from a :class:`~fliss.hdl.histogram.engine.Histogram` readout: the
    small alternative to :class:`~fliss.hdl.packets.histogram.HistogramPacketizer`, with
    the same ports, for builds without room for compact chunks (it ignores ``full_readout``).

    Each frame of ``2**(pixel_bits + 13 - shift)`` bins is sent as chunks of :data:`CHUNK_BINS`
    bins (all of them when there are fewer) as they come, by a
    :class:`~fliss.hdl.histogram.chunk.ChunkEmitter`: a :class:`~fliss.hdl.protocol.HistogramChunk`, then one u16
    count per bin, little-endian; the packets of
    :func:`fliss.protocol.histograms.encode_histogram` with ``full_readout``.

    Parameters
    ----------
    index_bits : int
        Width of the readout's flat index (up to 16).

    Members
    -------
    readout : In(stream.Signature(readout_layout(index_bits, COUNT_WIDTH)))
    shift : In(range(14))
        Bin shift of the frame being read out.
    pixel_bits : In(3)
        The frame holds ``2**pixel_bits`` pixels.
    first_pixel : In(6)
        Address of the frame's pixel 0.
    full_readout : In(1)
        Ignored: every chunk is full.
    packets : Out(stream.Signature(PacketBeat))
    """

    def __init__(self, *, index_bits=BIN_BITS):
        if not isinstance(index_bits, int) or not 1 <= index_bits <= MAX_FRAME_BITS:
            raise ValueError(f"Index width must be an integer from 1 to {MAX_FRAME_BITS} bits, "
                             f"not {index_bits!r}")
        self.index_bits = index_bits
        super().__init__(histogram_packetizer_members(index_bits))

    def elaborate(self, platform):
        m = Module()

        m.submodules.chunk = chunk = ChunkEmitter()
        frame = Signal(32)

        # Sizes that follow from the frame's bins, 2**frame_bits, out of constant tables indexed
        # by frame_bits (a LUT per bit, where shifts, comparisons and sums would be carry
        # chains): bins in a chunk, its packet length, and the first bin of the frame's last
        # chunk. They are registered as a chunk starts (for timing).
        frame_bits = Signal(range(MAX_FRAME_BITS + 1))
        m.d.comb += frame_bits.eq(self.pixel_bits + TIMESTAMP_BITS - self.shift)

        def table(function):
            values = [function(1 << bits) for bits in range(MAX_FRAME_BITS + 1)]
            return lookup(values, frame_bits, fill=values[-1])
        chunk_bins = table(lambda frame_bins: min(frame_bins, CHUNK_BINS))
        chunk_length = table(lambda frame_bins: CHUNK_HEADER_BYTES +
                             min(frame_bins, CHUNK_BINS) * COUNT_BYTES)
        last_first_bin = table(lambda frame_bins: max(frame_bins - CHUNK_BINS, 0))
        bins = Signal.like(chunk.size)
        length = Signal.like(chunk.length)
        last_chunk = Signal()
        with m.If(self.readout.valid & ~chunk.busy):
            m.d.sync += [
                bins.eq(chunk_bins),
                length.eq(chunk_length),
                last_chunk.eq(self.readout.p.index >= last_first_bin),
            ]

        # A chunk starts at the first bin that waits for one. Its header is made from the values
        # it describes: they hold until the chunk's first bin is taken (the bin waits on
        # `readout`; the frame's settings and number change only after its last bin), so none
        # is copied into a register.
        m.d.comb += [
            chunk.start.eq(self.readout.valid),
            chunk.size.eq(bins),
            chunk.length.eq(length),
            chunk.header.frame.eq(frame),
            chunk.header.first_bin.eq(self.readout.p.index),
            chunk.header.shift.eq(self.shift),
            chunk.header.pixel_bits.eq(self.pixel_bits),
            chunk.header.first_pixel.eq(self.first_pixel),
            chunk.header.last.eq(last_chunk),
            chunk.items.valid.eq(self.readout.valid),
            chunk.items.payload.eq(self.readout.p.count),
            self.readout.ready.eq(chunk.items.ready),
        ]
        wiring.connect(m, chunk.packets, wiring.flipped(self.packets))

        # The frame ends with the chunk that holds its last bin
        last_of_frame = Signal()
        with m.If(self.readout.valid & self.readout.ready):
            m.d.sync += last_of_frame.eq(self.readout.p.last)
        with m.If(chunk.done & last_of_frame):
            m.d.sync += frame.eq(frame + 1)

        return m
