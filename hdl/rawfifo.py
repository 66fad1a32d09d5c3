"""Raw-event FIFO between the event stream and the link, with drop counting."""

import numbers

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from .block_ram import DP16KD_DEPTH, RegisteredRam
from .event import Event
from .tdc import COUNTER_WIDTH
from .counters import count_event


__all__ = ["DEPTH", "MAX_DEPTH", "COUNTER_WIDTH", "EVENT_WIDTH", "check_depth", "RawFifo"]


#: Default FIFO depth, in events.
DEPTH = 512
#: Largest FIFO depth: a block RAM of :data:`~fliss.hdl.block_ram.DP16KD_DEPTH` words and the
#: two read registers.
MAX_DEPTH = DP16KD_DEPTH + 2
#: Width of one event in the FIFO, in bits.
EVENT_WIDTH = data.Layout.cast(Event).size


def check_depth(depth):
    """Raise :exc:`ValueError` unless ``depth`` is a valid FIFO depth (for the model too)."""
    if isinstance(depth, bool) or not isinstance(depth, numbers.Integral) or \
            not 4 <= depth <= MAX_DEPTH:
        raise ValueError(f"FIFO depth must be an integer from 4 to {MAX_DEPTH}, not {depth!r}")


class RawFifo(wiring.Component):
    """Event FIFO that never holds back its source.

    ``events`` is always ready. An event that arrives while the FIFO holds ``depth`` events is
    dropped and counted in ``dropped``; every other one is counted in ``accepted`` and comes out
    on ``output``, in order. Events go through an input register into a queue of ``depth - 2``
    events in a :class:`~fliss.hdl.block_ram.RegisteredRam`, whose two read registers hold
    one event each: the read (an event taken from the queue when the read register is empty or
    moves on) and the output register (``output``: on an ECP5, the block RAM's own, so the
    link's logic starts from a register next to the RAM). An event that arrives in cycle ``t``
    is written (or dropped) in cycle ``t + 1`` and, if the FIFO was empty, is on ``output`` from
    cycle ``t + 4``.

    Parameters
    ----------
    depth : int
        Capacity in events, from 4 (with 3, the queue behind the two registers would refuse an
        event while they are still empty) to :data:`MAX_DEPTH`.
    counter_width : int
        Width of ``accepted`` and ``dropped``, from 1 to 64 bits; they saturate.

    Members
    -------
    events : In(stream.Signature(Event))
        Events; ``ready`` is always high.
    output : Out(stream.Signature(Event))
        Events to the link.
    clear : In(1)
        Reset ``accepted`` and ``dropped``.
    level : Out(range(depth + 1))
        Events in the FIFO (not counting the input register).
    accepted : Out(counter_width)
        Events written into the FIFO.
    dropped : Out(counter_width)
        Events dropped because the FIFO was full.
    tally : Out(data.StructLayout)
        Strobes ``accepted`` and ``dropped``: high in each cycle its counter counts (and when it
        is full), for counters elsewhere.
    """

    def __init__(self, *, depth=DEPTH, counter_width=COUNTER_WIDTH):
        check_depth(depth)
        if not isinstance(counter_width, int) or not 1 <= counter_width <= 64:
            raise ValueError(f"Counter width must be an integer from 1 to 64 bits, "
                             f"not {counter_width!r}")
        self.depth = int(depth)
        self.counter_width = counter_width
        super().__init__({
            "events":   In(stream.Signature(Event)),
            "output":   Out(stream.Signature(Event)),
            "clear":    In(1),
            "level":    Out(range(depth + 1)),
            "accepted": Out(counter_width),
            "dropped":  Out(counter_width),
            "tally":    Out(data.StructLayout({"accepted": 1, "dropped": 1})),
        })

    def elaborate(self, platform):
        m = Module()

        entries = self.depth - 2
        m.submodules.storage = storage = RegisteredRam(depth=entries, width=EVENT_WIDTH,
                                                       output_enable=True)

        # Input register: nothing combinational between the source and the FIFO's write logic
        valid = Signal()
        payload = Signal(EVENT_WIDTH)
        m.d.comb += self.events.ready.eq(1)
        m.d.sync += valid.eq(self.events.valid), payload.eq(self.events.payload)

        # The queue: `queued` events in the RAM, from `read_at` on
        write_at = Signal(range(entries))
        read_at = Signal(range(entries))
        queued = Signal(range(entries + 1))
        middle = Signal()       # the RAM's first read register holds an event

        # Write side: never stalls
        write = Signal()
        drop = Signal()
        m.d.comb += [
            write.eq(valid & (queued != entries)),
            drop.eq(valid & (queued == entries)),
            storage.write_addr.eq(write_at),
            storage.write_data.eq(payload),
            storage.write_en.eq(write),
        ]

        # Counters
        count_event(m, self.accepted, write, self.clear, self.tally.accepted)
        count_event(m, self.dropped, drop, self.clear, self.tally.dropped)

        # Read side: the output register moves on when it is empty or taken (`take`); an event
        # leaves the queue into the first read register when it is empty or moves on (`read`).
        # (A read and a write of the same word at one edge cannot happen: the queue would be
        # both empty and full.)
        take = Signal()
        read = Signal()
        m.d.comb += [
            take.eq(~self.output.valid | self.output.ready),
            read.eq((queued != 0) & (~middle | take)),
            storage.read_addr.eq(read_at),
            storage.read_en.eq(read),
            storage.output_en.eq(take),
            self.output.payload.eq(storage.read_data),
            self.level.eq(queued + middle + self.output.valid),
        ]
        with m.If(write):
            m.d.sync += write_at.eq(Mux(write_at == entries - 1, 0, write_at + 1))
        with m.If(read):
            m.d.sync += read_at.eq(Mux(read_at == entries - 1, 0, read_at + 1))
        m.d.sync += queued.eq(queued + write - read)
        with m.If(read):
            m.d.sync += middle.eq(1)
        with m.Elif(take):
            m.d.sync += middle.eq(0)
        with m.If(take):
            m.d.sync += self.output.valid.eq(middle)

        return m
