"""The readout in windows, each weighed as a compact or a full chunk."""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ..event import ADDRESS_BITS
from .chunk import CHUNK_HEADER_BYTES, COMPACT_HEADER_BYTES, COUNT_BYTES
from .compact import RUN_BITS, CompactControl, token_length
from .layout import COUNT_WIDTH, MAX_SHIFT, readout_layout
from ..protocol import CHUNK_BINS, COMPACT_BYTES, HistogramChunk


__all__ = ["WindowScanner"]


#: Most token bytes one window can make (two 3-byte tokens a bin).
_WINDOW_TOKENS = 6 * CHUNK_BINS


class WindowScanner(wiring.Component):
    """The window scanner of :class:`~fliss.hdl.packets.histogram.HistogramPacketizer`:
    takes each window of ``min(CHUNK_BINS, bins)`` bins of a frame into the window buffer
    while the lengths of its compact tokens are counted (SCAN: one bin per cycle the readout
    offers), weighs the window's compact tokens against its full chunk (the rule of
    :mod:`fliss.protocol.histograms`), and hands it to the chunk emitter (``full``) or the
    compact encoder (``compact``), closing the compact chunk in progress first when the window
    does not fit in it or goes full. The settings are taken with each bin (a chunk carries those
    of its first bin; ``full_readout`` those of the frame's first bin).

    Readout beats are registered before any logic uses them (stage 1), and go into the buffer
    and the tallies the cycle after (stage 2).

    Parameters
    ----------
    index_bits : int
        Width of the readout's flat index.

    Members
    -------
    readout, shift, pixel_bits, first_pixel, full_readout : In
        As in :func:`~fliss.hdl.packets.histogram.histogram_packetizer_members`.
    buffer : Out(wiring.Signature({"addr": ..., "data": Out(COUNT_WIDTH), "en": Out(1)}))
        Write port of the window buffer (``CHUNK_BINS`` counts).
    window : Out(HistogramChunk)
        The window's full-chunk header: the frame's number and settings, the window's first bin
        and whether it ends the frame.
    bins : Out(range(CHUNK_BINS + 1))
        Bins in the window.
    length : Out(16)
        Length of the window's full chunk (registered).
    full : Out(wiring.Signature({"start": Out(1), "done": In(1)}))
        The chunk emitter: send the window as a HISTOGRAM chunk; the chunk's last byte is taken.
    compact : Out(CompactControl)
        The compact encoder.
    """

    def __init__(self, *, index_bits):
        self.index_bits = index_bits
        super().__init__({
            "readout":      In(stream.Signature(readout_layout(index_bits, COUNT_WIDTH))),
            "shift":        In(range(MAX_SHIFT + 1)),
            "pixel_bits":   In(range(ADDRESS_BITS + 1)),
            "first_pixel":  In(ADDRESS_BITS),
            "full_readout": In(1),
            "buffer":       Out(wiring.Signature({"addr": Out(range(CHUNK_BINS)),
                                                  "data": Out(COUNT_WIDTH), "en": Out(1)})),
            "window":       Out(HistogramChunk),
            "bins":         Out(range(CHUNK_BINS + 1)),
            "length":       Out(16),
            "full":         Out(wiring.Signature({"start": Out(1), "done": In(1)})),
            "compact":      Out(CompactControl),
        })

    def elaborate(self, platform):
        m = Module()

        frame = Signal(32)
        frame_start = Signal(init=1)    # the next bin taken is a frame's first
        full_readout = Signal()
        window = self.window
        window_bins = self.bins
        fresh_bytes = Signal(range(_WINDOW_TOKENS + 1))
        fresh_run = Signal(RUN_BITS)
        carried_bytes = Signal(range(_WINDOW_TOKENS + 1))
        carried_run = Signal(RUN_BITS)
        open_run = self.compact.open_run

        # Token lengths of a bin of count `c` after `r` empty bins
        def tally(total, empty, count):
            with m.If(count == 0):
                m.d.sync += empty.eq(empty + 1)
            with m.Else():
                m.d.sync += [
                    total.eq(total + Mux(empty == 0, 0, token_length(empty)) +
                             token_length(count)),
                    empty.eq(0),
                ]

        # The choices of DECIDE, registered in WEIGH (each is a carry chain)
        window_compact = Signal()
        fits = Signal()
        # The full chunk's length, registered: it holds for a cycle or more before its packet
        # starts (`window_bins` from SCAN_END)
        m.d.sync += self.length.eq(CHUNK_HEADER_BYTES + COUNT_BYTES * window_bins)

        # Stage 1 (SCAN): a beat of the readout into registers. Stage 2, the next cycle: its
        # count into the buffer, its tokens counted.
        beat_valid = Signal()
        beat = Signal.like(self.readout.p)
        beat_settings = Signal(data.StructLayout({      # (the settings as the beat came)
            "first_pixel": ADDRESS_BITS, "shift": range(MAX_SHIFT + 1),
            "pixel_bits": range(ADDRESS_BITS + 1), "full_readout": 1}))
        taken = Signal(range(CHUNK_BINS + 1))
        m.d.sync += beat_valid.eq(0)
        with m.If(beat_valid):
            m.d.comb += [
                self.buffer.addr.eq(window_bins),
                self.buffer.data.eq(beat.count),
                self.buffer.en.eq(1),
            ]
            with m.If(window_bins == 0):
                m.d.sync += [
                    window.first_bin.eq(beat.index),
                    window.frame.eq(frame),
                    window.first_pixel.eq(beat_settings.first_pixel),
                    window.shift.eq(beat_settings.shift),
                    window.pixel_bits.eq(beat_settings.pixel_bits),
                ]
                with m.If(frame_start):
                    m.d.sync += full_readout.eq(beat_settings.full_readout), frame_start.eq(0)
                # (the tallies start here: nothing before the window, or the open chunk's run)
                with m.If(beat.count != 0):
                    m.d.sync += [
                        fresh_bytes.eq(token_length(beat.count)), fresh_run.eq(0),
                        carried_bytes.eq(Mux(open_run == 0, 0, token_length(open_run)) +
                                         token_length(beat.count)),
                        carried_run.eq(0),
                    ]
                with m.Else():
                    m.d.sync += [
                        fresh_bytes.eq(0), fresh_run.eq(1),
                        carried_bytes.eq(0), carried_run.eq(open_run + 1),
                    ]
            with m.Else():
                tally(fresh_bytes, fresh_run, beat.count)
                tally(carried_bytes, carried_run, beat.count)
            m.d.sync += window_bins.eq(window_bins + 1), window.last.eq(beat.last)

        with m.FSM():
            with m.State("SCAN"):
                m.d.comb += self.readout.ready.eq(1)
                with m.If(self.readout.valid):
                    m.d.sync += [
                        beat_valid.eq(1), beat.eq(self.readout.p), taken.eq(taken + 1),
                        beat_settings.first_pixel.eq(self.first_pixel),
                        beat_settings.shift.eq(self.shift),
                        beat_settings.pixel_bits.eq(self.pixel_bits),
                        beat_settings.full_readout.eq(self.full_readout),
                    ]
                    with m.If(self.readout.p.last | (taken == CHUNK_BINS - 1)):
                        m.next = "SCAN_END"
            with m.State("SCAN_END"):       # (stage 2 of the window's last beat)
                m.next = "WEIGH"
            with m.State("WEIGH"):
                m.d.sync += [
                    window_compact.eq(~full_readout &
                                      (fresh_bytes + COMPACT_HEADER_BYTES <
                                       CHUNK_HEADER_BYTES + COUNT_BYTES * window_bins)),
                    fits.eq(self.compact.open_bytes + carried_bytes <= COMPACT_BYTES),
                ]
                m.next = "DECIDE"

            with m.State("DECIDE"):
                with m.If(window_compact):
                    m.d.comb += [self.compact.append.eq(1),
                                 self.compact.close.eq(self.compact.open & ~fits)]
                    m.next = "COMPACT"
                with m.Elif(self.compact.open):
                    m.d.comb += self.compact.close.eq(1)
                    m.next = "CLOSE"
                with m.Else():
                    m.d.comb += self.full.start.eq(1)
                    m.next = "FULL"

            with m.State("FULL"):
                with m.If(self.full.done):
                    m.next = "NEXT"
            with m.State("CLOSE"):          # (then the window goes full)
                with m.If(self.compact.done):
                    m.d.comb += self.full.start.eq(1)
                    m.next = "FULL"
            with m.State("COMPACT"):
                with m.If(self.compact.done & window.last):
                    m.next = "NEXT"
                with m.Elif(self.compact.done):
                    m.d.sync += window_bins.eq(0), taken.eq(0)
                    m.next = "SCAN"

            # The window is done: the next one, or the next frame
            with m.State("NEXT"):
                m.d.sync += window_bins.eq(0), taken.eq(0)
                with m.If(window.last):
                    m.d.sync += frame.eq(frame + 1), frame_start.eq(1)
                m.next = "SCAN"

        return m
