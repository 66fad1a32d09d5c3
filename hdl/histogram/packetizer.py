"""HISTOGRAM and HISTOGRAM_COMPACT packets from a histogram readout, whichever is shorter."""

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ..block_ram import RegisteredRam
from ..event import ADDRESS_BITS
from ..link.framing import PacketBeat
from .layout import BIN_BITS, COUNT_WIDTH, MAX_SHIFT, readout_layout
from ..protocol import (CHUNK_BINS, COMPACT_BYTES, HISTOGRAM_COUNT_BITS, MAX_FRAME_BITS,
                        HistogramChunk, HistogramCompact, PacketType)


__all__ = ["histogram_packetizer_members", "HistogramPacketizer"]


_FULL_HEADER = data.Layout.cast(HistogramChunk).size // 8
_COMPACT_HEADER = data.Layout.cast(HistogramCompact).size // 8
_COUNT_BYTES = HISTOGRAM_COUNT_BITS // 8
assert COUNT_WIDTH == HISTOGRAM_COUNT_BITS, "the readout's counts go out as they are"
#: Most token bytes one window can make (two 3-byte tokens a bin), and the widest run.
_WINDOW_TOKENS = 6 * CHUNK_BINS
_RUN_BITS = MAX_FRAME_BITS


def _token_length(value):
    # Bytes of the token of a run of `value` empty bins or of a count `value` (LEB128 of
    # 2 * value or 2 * value + 1): 1 below 64, 2 below 8192, else 3.
    return Mux(value < 64, 1, Mux(value < 8192, 2, 3))


def histogram_packetizer_members(index_bits):
    """Members of a histogram packetizer (this one, or the full-chunk one of
    :mod:`fliss.hdl.link.packetizer`): the readout's bins and the frame's settings in, packets out."""
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

    Each window of ``min(CHUNK_BINS, bins)`` bins of a frame is taken into a buffer while the
    lengths of its compact tokens are counted (SCAN: one bin per cycle the readout offers);
    then the window is either sent as a HISTOGRAM chunk from the buffer (FULL), or its tokens
    are appended to the compact chunk in progress (ENCODE), which is sent (CLOSE) when the next
    window does not fit in it, a window goes full, or the frame ends. The rule is that of
    :mod:`fliss.protocol.histograms`. The settings are taken with each bin (a chunk carries
    those of its first bin; ``full_readout`` those of the frame's first bin).

    Cycles: SCAN takes a bin in every cycle the readout offers one (the readout offers one
    every 4 cycles); ENCODE takes 2 cycles an empty bin, 3 a bin with a count and one a token
    byte; FULL and CLOSE send a byte every 2 cycles at most, far faster than a UART. Readout
    beats and RAM words are registered before any logic uses them. Cost: some 740 LUTs, 400
    flip-flops and two block RAMs on an iCE40 (the full-only
    :class:`~fliss.hdl.link.packetizer.FullHistogramPacketizer`: 175 LUTs, no RAM).

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
        if not isinstance(index_bits, int) or not 1 <= index_bits <= _RUN_BITS:
            raise ValueError(f"Index width must be an integer from 1 to {_RUN_BITS} bits, not "
                             f"{index_bits!r}")
        self.index_bits = index_bits
        super().__init__(histogram_packetizer_members(index_bits))

    def elaborate(self, platform):
        m = Module()

        # The window's counts, and the tokens of the compact chunk in progress
        # (block RAMs with a registered read: a word is there two cycles after its address)
        m.submodules.counts = counts = RegisteredRam(depth=CHUNK_BINS, width=COUNT_WIDTH)
        m.submodules.tokens = tokens = RegisteredRam(depth=COMPACT_BYTES, width=8)

        frame = Signal(32)
        frame_start = Signal(init=1)    # the next bin taken is a frame's first
        full_readout = Signal()
        split = Signal(HistogramChunk)  # frame, first_pixel, shift, pixel_bits of this frame
        window_first = Signal(16)
        window_bins = Signal(range(CHUNK_BINS + 1))
        window_last = Signal()          # the window ends the frame
        fresh_bytes = Signal(range(_WINDOW_TOKENS + 1))
        fresh_run = Signal(_RUN_BITS + 1)
        carried_bytes = Signal(range(_WINDOW_TOKENS + 1))
        carried_run = Signal(_RUN_BITS + 1)
        # the compact chunk in progress
        open_ = Signal()
        open_first = Signal(16)
        open_last = Signal(16)
        open_bytes = Signal(range(COMPACT_BYTES + 1))
        open_run = Signal(_RUN_BITS + 1)
        close_last = Signal()
        then_full = Signal()            # after CLOSE: send the window full, else encode it
        # walking through a buffer, and the token being written
        step = Signal(range(max(CHUNK_BINS, COMPACT_BYTES, _COMPACT_HEADER) + 1))
        byte = Signal()
        run = Signal(_RUN_BITS + 1)
        value = Signal(_RUN_BITS + 2)
        pending_count = Signal(COUNT_WIDTH)
        # the buffers' words, registered again as they come (the RAMs may sit far from this
        # logic). A RAM gives a word two cycles after its address: each word is addressed
        # while the one before is used (`ahead`: the address is `step + 1`), or, for the
        # first, from the state before (`first`: the address is 0). The address is one LUT
        # from registers, as the RAMs may be far: `step + 1` is kept in `step_next`, and
        # `ahead` and `first` are set with the state (:func:`goto`).
        word = Signal(COUNT_WIDTH)
        token = Signal(8)
        step_next = Signal.like(step, init=1)
        ahead = Signal()
        first = Signal()
        full_header = Signal(HistogramChunk)
        compact_header = Signal(HistogramCompact)

        def goto(state):
            m.next = state
            m.d.sync += [ahead.eq(state in ("FULL_COUNT", "ENCODE_FETCH", "CLOSE_TOKEN")),
                         first.eq(state in ("FULL_HEADER", "CLOSE_HEADER"))]

        def advance():
            return [step.eq(step_next), step_next.eq(step_next + 1)]

        def restart():
            return [step.eq(0), step_next.eq(1)]

        address = Mux(first, 0, Mux(ahead, step_next, step))
        m.d.comb += [
            counts.read_addr.eq(address),
            counts.read_en.eq(1),
            tokens.read_addr.eq(address),
            tokens.read_en.eq(1),
            tokens.write_addr.eq(open_bytes),
            tokens.write_data.eq(Cat(value[:7], value >= 0x80)),
            full_header.eq(split),
            full_header.first_bin.eq(window_first),
            full_header.last.eq(window_last),
            compact_header.frame.eq(split.frame),
            compact_header.first_pixel.eq(split.first_pixel),
            compact_header.shift.eq(split.shift),
            compact_header.pixel_bits.eq(split.pixel_bits),
            compact_header.first_bin.eq(open_first),
            compact_header.last_bin.eq(open_last),
            compact_header.last.eq(close_last),
        ]

        # Token lengths of a bin of count `c` after `r` empty bins
        def tally(total, empty, count):
            with m.If(count == 0):
                m.d.sync += empty.eq(empty + 1)
            with m.Else():
                m.d.sync += [
                    total.eq(total + Mux(empty == 0, 0, _token_length(empty)) +
                             _token_length(count)),
                    empty.eq(0),
                ]

        # The choices of DECIDE, registered in WEIGH (each is a carry chain)
        window_compact = Signal()
        fits = Signal()
        # The packets' lengths, registered: each holds for a cycle or more before its packet
        # starts (`window_bins` from SCAN_END, `open_bytes` from ENCODE_TOKEN)
        full_length = Signal(16)
        compact_length = Signal(16)
        m.d.sync += [
            full_length.eq(_FULL_HEADER + _COUNT_BYTES * window_bins),
            compact_length.eq(_COMPACT_HEADER + open_bytes),
        ]

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
                counts.write_addr.eq(window_bins),
                counts.write_data.eq(beat.count),
                counts.write_en.eq(1),
            ]
            with m.If(window_bins == 0):
                m.d.sync += [
                    window_first.eq(beat.index),
                    split.frame.eq(frame),
                    split.first_pixel.eq(beat_settings.first_pixel),
                    split.shift.eq(beat_settings.shift),
                    split.pixel_bits.eq(beat_settings.pixel_bits),
                ]
                with m.If(frame_start):
                    m.d.sync += full_readout.eq(beat_settings.full_readout), frame_start.eq(0)
                # (the tallies start here: nothing before the window, or the open chunk's run)
                with m.If(beat.count != 0):
                    m.d.sync += [
                        fresh_bytes.eq(_token_length(beat.count)), fresh_run.eq(0),
                        carried_bytes.eq(Mux(open_run == 0, 0, _token_length(open_run)) +
                                         _token_length(beat.count)),
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
            m.d.sync += window_bins.eq(window_bins + 1), window_last.eq(beat.last)

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
                        m.d.sync += restart()
                        goto("SCAN_END")
            with m.State("SCAN_END"):       # (stage 2 of the window's last beat)
                goto("WEIGH")
            with m.State("WEIGH"):
                m.d.sync += [
                    window_compact.eq(~full_readout & (fresh_bytes + _COMPACT_HEADER <
                                                       _FULL_HEADER + _COUNT_BYTES * window_bins)),
                    fits.eq(open_bytes + carried_bytes <= COMPACT_BYTES),
                ]
                goto("DECIDE")

            with m.State("DECIDE"):
                m.d.sync += *restart(), byte.eq(0)
                with m.If(window_compact):
                    with m.If(open_ & fits):
                        m.d.sync += run.eq(open_run)
                        goto("ENCODE_LOAD")
                    with m.Elif(open_):
                        m.d.sync += then_full.eq(0), close_last.eq(0)
                        goto("CLOSE")
                    with m.Else():
                        goto("OPEN")
                with m.Else():
                    with m.If(open_):
                        m.d.sync += then_full.eq(1), close_last.eq(0)
                        goto("CLOSE")
                    with m.Else():
                        goto("FULL")

            # A window as a HISTOGRAM chunk: header, then its counts from the buffer
            with m.State("FULL"):
                m.d.comb += [
                    self.packets.valid.eq(1),
                    self.packets.p.first.eq(1),
                    self.packets.p.header.type.eq(PacketType.HISTOGRAM),
                    self.packets.p.header.length.eq(full_length),
                ]
                with m.If(self.packets.ready):
                    goto("FULL_HEADER")
            with m.State("FULL_HEADER"):
                m.d.comb += [
                    self.packets.valid.eq(1),
                    self.packets.p.header.type.eq(PacketType.HISTOGRAM),
                    self.packets.p.header.length.eq(full_length),
                    self.packets.p.data.eq(full_header.as_value().word_select(step, 8)),
                ]
                with m.If(self.packets.ready):
                    m.d.sync += advance()
                    with m.If(step == _FULL_HEADER - 1):
                        m.d.sync += restart()
                        goto("FULL_LOAD")
            with m.State("FULL_LOAD"):      # (the buffer's word for `step` comes next cycle)
                goto("FULL_FETCH")
            with m.State("FULL_FETCH"):
                m.d.sync += word.eq(counts.read_data)
                goto("FULL_COUNT")
            with m.State("FULL_COUNT"):
                final = byte & (step == window_bins - 1)
                m.d.comb += [
                    self.packets.valid.eq(1),
                    self.packets.p.header.type.eq(PacketType.HISTOGRAM),
                    self.packets.p.header.length.eq(full_length),
                    self.packets.p.data.eq(word.word_select(byte, 8)),
                    self.packets.p.last.eq(final),
                ]
                with m.If(self.packets.ready):
                    m.d.sync += byte.eq(~byte)
                    with m.If(byte):
                        m.d.sync += advance()
                        goto("FULL_LOAD")
                    with m.If(final):
                        goto("NEXT")

            # A compact window: its tokens after those of the chunk in progress
            with m.State("OPEN"):
                m.d.sync += [
                    open_.eq(1), open_first.eq(window_first), open_bytes.eq(0),
                    run.eq(0), *restart(),
                ]
                goto("ENCODE_LOAD")
            with m.State("ENCODE_LOAD"):
                with m.If(step == window_bins):
                    m.d.sync += open_run.eq(run), open_last.eq(window_first + window_bins - 1)
                    with m.If(window_last):
                        m.d.sync += close_last.eq(1), *restart()
                        goto("CLOSE")
                    with m.Else():
                        m.d.sync += window_bins.eq(0), taken.eq(0)
                        goto("SCAN")
                with m.Else():
                    goto("ENCODE_FETCH")
            with m.State("ENCODE_FETCH"):
                m.d.sync += word.eq(counts.read_data)
                goto("ENCODE_BIN")
            with m.State("ENCODE_BIN"):
                m.d.sync += advance()
                with m.If(word == 0):
                    m.d.sync += run.eq(run + 1)
                    goto("ENCODE_FETCH")
                    with m.If(step + 1 == window_bins):
                        goto("ENCODE_LOAD")
                with m.Elif(run != 0):
                    m.d.sync += value.eq(Cat(Const(1, 1), run)), pending_count.eq(word)
                    goto("ENCODE_TOKEN")
                with m.Else():
                    m.d.sync += value.eq(Cat(Const(0, 1), word)), pending_count.eq(0)
                    goto("ENCODE_TOKEN")
            with m.State("ENCODE_TOKEN"):
                m.d.comb += tokens.write_en.eq(1)
                m.d.sync += open_bytes.eq(open_bytes + 1), value.eq(value >> 7)
                with m.If(value < 0x80):
                    m.d.sync += run.eq(0)
                    with m.If(pending_count != 0):
                        m.d.sync += value.eq(Cat(Const(0, 1), pending_count)),
                        m.d.sync += pending_count.eq(0)
                    with m.Else():
                        goto("ENCODE_LOAD")

            # The compact chunk in progress as a HISTOGRAM_COMPACT packet
            with m.State("CLOSE"):
                m.d.comb += [
                    self.packets.valid.eq(1),
                    self.packets.p.first.eq(1),
                    self.packets.p.header.type.eq(PacketType.HISTOGRAM_COMPACT),
                    self.packets.p.header.length.eq(compact_length),
                ]
                with m.If(self.packets.ready):
                    m.d.sync += restart()
                    goto("CLOSE_HEADER")
            with m.State("CLOSE_HEADER"):
                final = (step == _COMPACT_HEADER - 1) & (open_bytes == 0)
                m.d.comb += [
                    self.packets.valid.eq(1),
                    self.packets.p.header.type.eq(PacketType.HISTOGRAM_COMPACT),
                    self.packets.p.header.length.eq(compact_length),
                    self.packets.p.data.eq(compact_header.as_value().word_select(step, 8)),
                    self.packets.p.last.eq(final),
                ]
                with m.If(self.packets.ready):
                    m.d.sync += advance()
                    with m.If(final):
                        goto("CLOSED")
                    with m.Elif(step == _COMPACT_HEADER - 1):
                        m.d.sync += restart()
                        goto("CLOSE_LOAD")
            with m.State("CLOSE_LOAD"):
                goto("CLOSE_FETCH")
            with m.State("CLOSE_FETCH"):
                m.d.sync += token.eq(tokens.read_data)
                goto("CLOSE_TOKEN")
            with m.State("CLOSE_TOKEN"):
                final = step == open_bytes - 1
                m.d.comb += [
                    self.packets.valid.eq(1),
                    self.packets.p.header.type.eq(PacketType.HISTOGRAM_COMPACT),
                    self.packets.p.header.length.eq(compact_length),
                    self.packets.p.data.eq(token),
                    self.packets.p.last.eq(final),
                ]
                with m.If(self.packets.ready):
                    m.d.sync += advance()
                    goto("CLOSE_LOAD")
                    with m.If(final):
                        goto("CLOSED")
            with m.State("CLOSED"):
                m.d.sync += open_.eq(0), open_run.eq(0), *restart(), byte.eq(0)
                with m.If(close_last):
                    goto("NEXT")
                with m.Elif(then_full):
                    goto("FULL")
                with m.Else():
                    goto("OPEN")

            # The window is done: the next one, or the next frame
            with m.State("NEXT"):
                m.d.sync += window_bins.eq(0), taken.eq(0)
                with m.If(window_last):
                    m.d.sync += frame.eq(frame + 1), frame_start.eq(1), close_last.eq(0)
                goto("SCAN")

        return m
