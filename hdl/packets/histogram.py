"""HISTOGRAM and HISTOGRAM_COMPACT packets from a histogram readout, whichever is shorter."""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from ..block_ram import RegisteredRam
from ..event import ADDRESS_BITS
from ..link.framing import PacketBeat
from ..histogram.chunk import ChunkEmitter
from ..histogram.compact import CompactEncoder
from ..histogram.layout import BIN_BITS, COUNT_WIDTH, MAX_SHIFT, readout_layout
from ..histogram.scanner import WindowScanner
from ..protocol import CHUNK_BINS, COMPACT_BYTES, MAX_FRAME_BITS


__all__ = ["histogram_packetizer_members", "HistogramPacketizer"]


def histogram_packetizer_members(index_bits):
    """Members of a histogram packetizer (this one, or the full-chunk one of
    :mod:`fliss.hdl.packets.histogram_full`): the readout's bins and the frame's settings in, packets out."""
    return {
        "readout":      In(stream.Signature(readout_layout(index_bits, COUNT_WIDTH))),
        "shift":        In(range(MAX_SHIFT + 1)),
        "pixel_bits":   In(range(ADDRESS_BITS + 1)),
        "first_pixel":  In(ADDRESS_BITS),
        "full_readout": In(1),
        "packets":      Out(stream.Signature(PacketBeat)),
    }


class HistogramPacketizer(wiring.Component):
    """HISTOGRAM and HISTOGRAM_COMPACT packets from a :class:`~fliss.hdl.histogram.engine.Histogram`
    readout, as :func:`fliss.protocol.histograms.encode_histogram` makes them.

    Three blocks make the packets. The :class:`~fliss.hdl.histogram.scanner.WindowScanner` takes
    each window of ``min(CHUNK_BINS, bins)`` bins of a frame into the window buffer while the
    lengths of its compact tokens are counted, and weighs them against the window's full chunk
    (the rule of :mod:`fliss.protocol.histograms`); the window then either goes to the
    :class:`~fliss.hdl.histogram.chunk.ChunkEmitter`, which sends it as a HISTOGRAM chunk from
    the buffer, or to the :class:`~fliss.hdl.histogram.compact.CompactEncoder`, which appends
    its tokens to the compact chunk in progress in the token buffer. That chunk is sent, by the
    chunk emitter again, when the next window does not fit in it, a window goes full, or the
    frame ends. The settings are taken with each bin (a chunk carries those of its first bin;
    ``full_readout`` those of the frame's first bin).

    Cycles: a bin is taken in every cycle the readout offers one (the readout offers one every
    4 cycles); encoding takes 2 cycles an empty bin, 3 a bin with a count and one a token byte;
    a chunk goes out at a byte every 2 cycles at most, far faster than a UART. Readout beats and
    RAM words are registered before any logic uses them. Cost: some 770 LUTs, 500 flip-flops
    and two block RAMs on an iCE40 (the full-only
    :class:`~fliss.hdl.packets.histogram_full.FullHistogramPacketizer`: 175 LUTs, no RAM).

    Parameters
    ----------
    index_bits : int
        Width of the readout's flat index (up to 16).

    Members
    -------
    readout : In(stream.Signature(readout_layout(index_bits, COUNT_WIDTH)))
        The frame's bins in flat index order, ``last`` on its final bin.
    shift : In(range(14))
        Bin shift of the frame being read out.
    pixel_bits : In(3)
        The frame holds ``2**pixel_bits`` pixels.
    first_pixel : In(6)
        Address of the frame's pixel 0.
    full_readout : In(1)
        Send every window as a HISTOGRAM chunk.
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

        # The window's counts, and the tokens of the compact chunk in progress (block RAMs with
        # a registered read: a word is there two cycles after its address)
        m.submodules.counts = counts = RegisteredRam(depth=CHUNK_BINS, width=COUNT_WIDTH)
        m.submodules.tokens = tokens = RegisteredRam(depth=COMPACT_BYTES, width=8)
        m.submodules.scanner = scanner = WindowScanner(index_bits=self.index_bits)
        m.submodules.compact = compact = CompactEncoder()
        m.submodules.chunk = chunk = ChunkEmitter(compact=True)

        # The readout into windows; each window to the compact encoder or the chunk emitter
        for name in ("shift", "pixel_bits", "first_pixel", "full_readout"):
            m.d.comb += getattr(scanner, name).eq(getattr(self, name))
        wiring.connect(m, wiring.flipped(self.readout), scanner.readout)
        wiring.connect(m, scanner.compact, compact.control)
        m.d.comb += [
            counts.write_addr.eq(scanner.buffer.addr),
            counts.write_data.eq(scanner.buffer.data),
            counts.write_en.eq(scanner.buffer.en),
            compact.window.eq(scanner.window),
            compact.bins.eq(scanner.bins),
            tokens.write_addr.eq(compact.tokens.addr),
            tokens.write_data.eq(compact.tokens.data),
            tokens.write_en.eq(compact.tokens.en),
        ]

        # Chunks: a window full, or the compact chunk in progress
        sending = compact.send.busy
        m.d.comb += [
            chunk.start.eq(scanner.full.start | compact.send.start),
            scanner.full.done.eq(chunk.done),
            compact.send.done.eq(chunk.done),
            chunk.compact.eq(sending),
            chunk.header.eq(scanner.window),
            chunk.compact_header.eq(compact.header),
            chunk.length.eq(Mux(sending, compact.length, scanner.length)),
            chunk.size.eq(Mux(sending, compact.control.open_bytes, scanner.bins)),
        ]
        wiring.connect(m, chunk.packets, wiring.flipped(self.packets))

        # The buffers, read by the compact encoder (the window's counts) or by the chunk emitter
        # (the counts or the tokens of the chunk it sends). The emitter's item is read when it
        # asks for one (the word comes the cycle after; the emitter asks without waiting for
        # `valid`), at the address of the next. Only one reads the window buffer at a time,
        # and the address of the other is 0 then: the encoder's while it is idle, the
        # emitter's between chunks.
        fetched = Signal()
        m.d.sync += fetched.eq(chunk.items.ready & ~fetched)
        m.d.comb += [
            counts.read_addr.eq(compact.buffer_addr | chunk.taken),
            counts.read_en.eq(1),
            compact.buffer_data.eq(counts.read_data),
            tokens.read_addr.eq(chunk.taken),
            tokens.read_en.eq(1),
            chunk.items.valid.eq(fetched),
            chunk.items.payload.eq(Mux(sending, tokens.read_data, counts.read_data)),
        ]

        return m
