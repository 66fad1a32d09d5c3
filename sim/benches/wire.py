"""A bench-side player and recorder of frame bytes, so that a cocotb test sends a whole frame and
reads back what came out with a few accesses, instead of one per clock cycle.

Not gateware of FLISS: it stands in the bench's top level beside the block under test, in
place of a testbench loop that would wake up at every edge.
"""

from amaranth.hdl import Cat, Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out


__all__ = ["WireBench"]


class WireBench(wiring.Component):
    """Plays one frame into ``o`` at up to one byte per cycle, records every byte of ``i``.

    The bench puts a frame on ``frame`` (its first byte in bits 0 to 7) and its length on
    ``length``, and holds ``go`` high for one cycle: the player takes both, and sends the bytes
    as ``o`` takes them. ``i`` is always ready: each byte it gives is shifted into the top of
    ``record`` (so that after ``n`` bytes the newest ``n`` are its top ``n`` bytes, the oldest
    first) and counted in ``received``, which never resets. ``answered`` is high once the frame
    has been sent and a frame delimiter (a zero byte) has come in since ``go``.

    Parameters
    ----------
    play_bytes : int
        The longest frame the player takes.
    record_bytes : int
        The bytes ``record`` keeps; the bench reads them before more than this come in.
    """

    def __init__(self, *, play_bytes, record_bytes):
        self.play_bytes, self.record_bytes = play_bytes, record_bytes
        super().__init__({
            "frame":    In(8 * play_bytes),
            "length":   In(range(play_bytes + 1)),
            "go":       In(1),
            "record":   Out(8 * record_bytes),
            "received": Out(32),
            "answered": Out(1),
            "o":        Out(stream.Signature(8)),
            "i":        In(stream.Signature(8)),
        })

    def elaborate(self, platform):
        m = Module()

        shift = Signal(8 * self.play_bytes)
        left = Signal(range(self.play_bytes + 1))
        with m.If(self.go):
            m.d.sync += [shift.eq(self.frame), left.eq(self.length)]
        with m.Elif(self.o.valid & self.o.ready):
            m.d.sync += [shift.eq(shift >> 8), left.eq(left - 1)]
        m.d.comb += [self.o.valid.eq(left != 0), self.o.payload.eq(shift[:8])]

        delimited = Signal()
        m.d.comb += self.i.ready.eq(1)
        with m.If(self.i.valid):
            m.d.sync += [self.record.eq(Cat(self.record[8:], self.i.payload)),
                         self.received.eq(self.received + 1)]
        with m.If(self.go):
            m.d.sync += delimited.eq(0)
        with m.Elif(self.i.valid & (self.i.payload == 0)):
            m.d.sync += delimited.eq(1)
        m.d.comb += self.answered.eq((left == 0) & delimited & ~self.go)
        return m
