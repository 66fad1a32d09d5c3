"""Compact chunks: windows of counts as tokens, gathered into a HISTOGRAM_COMPACT chunk."""

from amaranth.hdl import Cat, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from .chunk import COMPACT_HEADER_BYTES
from .layout import COUNT_WIDTH
from ..protocol import CHUNK_BINS, COMPACT_BYTES, MAX_FRAME_BITS, HistogramChunk, HistogramCompact


__all__ = ["RUN_BITS", "token_length", "CompactControl", "CompactEncoder"]


#: Width of a run of empty bins: up to a frame's ``2**MAX_FRAME_BITS``.
RUN_BITS = MAX_FRAME_BITS + 1


def token_length(value):
    """Bytes of the token of a run of ``value`` empty bins or of a count ``value`` (LEB128 of
    ``2 * value`` or ``2 * value + 1``): 1 below 64, 2 below 8192, else 3."""
    return Mux(value < 64, 1, Mux(value < 8192, 2, 3))


#: The compact encoder's controls, seen from the block that drives it (the window scanner of
#: :class:`~fliss.hdl.packets.histogram.HistogramPacketizer`). A job is taken while the
#: encoder is idle: ``append`` encodes the window into the chunk in progress (a new one if none
#: is open), ``close`` sends the chunk in progress first; ``close`` alone sends it and ends.
#: ``done`` is high in the job's last cycle (the window is encoded and, if it ends the frame,
#: its chunk sent). ``open``, ``open_bytes`` and ``open_run`` describe the chunk in progress:
#: its token bytes, and the empty bins since its last token.
CompactControl = wiring.Signature({
    "append":     Out(1),
    "close":      Out(1),
    "done":       In(1),
    "open":       In(1),
    "open_bytes": In(range(COMPACT_BYTES + 1)),
    "open_run":   In(RUN_BITS),
})


class CompactEncoder(wiring.Component):
    """The compact chunks of :class:`~fliss.hdl.packets.histogram.HistogramPacketizer`: a
    window's counts, read from the window buffer, become tokens appended to the chunk in
    progress in the token buffer; a chunk closed is sent by the chunk emitter
    (:class:`~fliss.hdl.histogram.chunk.ChunkEmitter`), from ``header`` and the token buffer.

    Cycles: 2 an empty bin, 3 a bin with a count, and one a token byte. Buffer words are
    registered before any logic uses them.

    Members
    -------
    control : In(CompactControl)
    window : In(HistogramChunk)
        The window being encoded: its first bin, whether it ends the frame, and the settings
        the chunk's header carries. Held through a job.
    bins : In(range(CHUNK_BINS + 1))
        Bins in the window. Held through a job.
    buffer_addr : Out(range(CHUNK_BINS))
        Read address of the window buffer (a :class:`~fliss.hdl.block_ram.RegisteredRam`:
        its word comes two cycles later; 0 while idle) ...
    buffer_data : In(COUNT_WIDTH)
        ... and its read data.
    tokens : Out(wiring.Signature({"addr": ..., "data": Out(8), "en": Out(1)}))
        Write port of the token buffer (``COMPACT_BYTES`` bytes).
    send : Out(wiring.Signature({"start": Out(1), "busy": Out(1), "done": In(1)}))
        The chunk emitter: send the chunk in progress (``busy`` while it does); its last byte is
        taken.
    header : Out(HistogramCompact)
        The header of the chunk in progress.
    length : Out(16)
        Its packet's length (registered).
    """

    control:     In(CompactControl)
    window:      In(HistogramChunk)
    bins:        In(range(CHUNK_BINS + 1))
    buffer_addr: Out(range(CHUNK_BINS))
    buffer_data: In(COUNT_WIDTH)
    tokens:      Out(wiring.Signature({"addr": Out(range(COMPACT_BYTES)), "data": Out(8),
                                       "en": Out(1)}))
    send:        Out(wiring.Signature({"start": Out(1), "busy": Out(1), "done": In(1)}))
    header:      Out(HistogramCompact)
    length:      Out(16)

    def elaborate(self, platform):
        m = Module()

        open_ = Signal()
        open_first = Signal(16)
        open_last = Signal(16)
        open_bytes = Signal(range(COMPACT_BYTES + 1))
        open_run = Signal(RUN_BITS)
        close_last = Signal()           # the chunk ends the frame
        then_open = Signal()            # after CLOSED: open a chunk for the window
        # walking through the window, and the token being written
        step = Signal(range(CHUNK_BINS + 1))
        run = Signal(RUN_BITS)
        value = Signal(RUN_BITS + 1)
        pending_count = Signal(COUNT_WIDTH)
        # the buffer's words, registered again as they come (the RAM may sit far from this
        # logic). The RAM gives a word two cycles after its address: each word is addressed
        # while the one before is used (`ahead`: the address is `step + 1`), or, for the
        # first, from the state before (while idle, the address is 0: `first`). The address
        # is one LUT from registers, as the RAM may be far: `step + 1` is kept in `step_next`,
        # and `ahead` and `first` are set with the state (``goto``).
        word = Signal(COUNT_WIDTH)
        step_next = Signal.like(step, init=1)
        ahead = Signal()
        first = Signal()

        def goto(state):
            m.next = state
            m.d.sync += [ahead.eq(state == "ENCODE_FETCH"), first.eq(state == "IDLE")]

        def advance():
            return [step.eq(step_next), step_next.eq(step_next + 1)]

        def restart():
            return [step.eq(0), step_next.eq(1)]

        def close(last, then):
            m.d.comb += self.send.start.eq(1)
            m.d.sync += close_last.eq(last), then_open.eq(then)
            goto("SEND")

        m.d.comb += [
            self.buffer_addr.eq(Mux(first, 0, Mux(ahead, step_next, step))),
            self.tokens.addr.eq(open_bytes),
            self.tokens.data.eq(Cat(value[:7], value >= 0x80)),
            self.control.open.eq(open_),
            self.control.open_bytes.eq(open_bytes),
            self.control.open_run.eq(open_run),
            self.header.frame.eq(self.window.frame),
            self.header.first_pixel.eq(self.window.first_pixel),
            self.header.shift.eq(self.window.shift),
            self.header.pixel_bits.eq(self.window.pixel_bits),
            self.header.first_bin.eq(open_first),
            self.header.last_bin.eq(open_last),
            self.header.last.eq(close_last),
        ]
        m.d.sync += self.length.eq(COMPACT_HEADER_BYTES + open_bytes)

        with m.FSM():
            with m.State("IDLE"):
                m.d.sync += restart()
                with m.If(self.control.close):
                    close(last=0, then=self.control.append)
                with m.Elif(self.control.append & open_):
                    m.d.sync += run.eq(open_run)
                    goto("ENCODE_LOAD")
                with m.Elif(self.control.append):
                    goto("OPEN")

            # The window's tokens after those of the chunk in progress
            with m.State("OPEN"):
                m.d.sync += [
                    open_.eq(1), open_first.eq(self.window.first_bin), open_bytes.eq(0),
                    run.eq(0), *restart(),
                ]
                goto("ENCODE_LOAD")
            with m.State("ENCODE_LOAD"):
                with m.If(step == self.bins):
                    m.d.sync += [open_run.eq(run),
                                 open_last.eq(self.window.first_bin + self.bins - 1)]
                    with m.If(self.window.last):
                        close(last=1, then=0)
                    with m.Else():
                        m.d.comb += self.control.done.eq(1)
                        goto("IDLE")
                with m.Else():
                    goto("ENCODE_FETCH")
            with m.State("ENCODE_FETCH"):
                m.d.sync += word.eq(self.buffer_data)
                goto("ENCODE_BIN")
            with m.State("ENCODE_BIN"):
                m.d.sync += advance()
                with m.If(word == 0):
                    m.d.sync += run.eq(run + 1)
                    goto("ENCODE_FETCH")
                    with m.If(step + 1 == self.bins):
                        goto("ENCODE_LOAD")
                with m.Elif(run != 0):
                    m.d.sync += value.eq(Cat(Const(1, 1), run)), pending_count.eq(word)
                    goto("ENCODE_TOKEN")
                with m.Else():
                    m.d.sync += value.eq(Cat(Const(0, 1), word)), pending_count.eq(0)
                    goto("ENCODE_TOKEN")
            with m.State("ENCODE_TOKEN"):
                m.d.comb += self.tokens.en.eq(1)
                m.d.sync += open_bytes.eq(open_bytes + 1), value.eq(value >> 7)
                with m.If(value < 0x80):
                    m.d.sync += run.eq(0)
                    with m.If(pending_count != 0):
                        m.d.sync += value.eq(Cat(Const(0, 1), pending_count)),
                        m.d.sync += pending_count.eq(0)
                    with m.Else():
                        goto("ENCODE_LOAD")

            # The chunk in progress is sent; then a new one opens for the window, or the job
            # is done
            with m.State("SEND"):
                m.d.comb += self.send.busy.eq(1)
                with m.If(self.send.done):
                    goto("CLOSED")
            with m.State("CLOSED"):
                m.d.sync += open_.eq(0), open_run.eq(0), *restart()
                with m.If(then_open):
                    goto("OPEN")
                with m.Else():
                    m.d.comb += self.control.done.eq(1)
                    goto("IDLE")

        return m
