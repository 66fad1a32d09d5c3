"""Raw-event FIFO between the event stream and the link, with drop counting."""

from amaranth.hdl import Module, Signal
from amaranth.lib import data, fifo, stream, wiring
from amaranth.lib.wiring import In, Out

from .event import Event
from .tdc import COUNTER_WIDTH, count_event


__all__ = ["DEPTH", "COUNTER_WIDTH", "EVENT_WIDTH", "RawFifo"]


#: Default FIFO depth, in events.
DEPTH = 512
#: Width of one event in the FIFO, in bits.
EVENT_WIDTH = data.Layout.cast(Event).size


class RawFifo(wiring.Component):
    """Event FIFO that never holds back its source.

    ``events`` is always ready. An event that arrives while the FIFO holds ``depth`` events is
    dropped and counted in ``dropped``; every other one is counted in ``accepted`` and comes out
    on ``output``, in order. Events go through an input register, then into an
    :class:`amaranth.lib.fifo.SyncFIFOBuffered` (block RAM, registered read) of ``depth - 1``
    events, then the output register: an event that arrives in cycle ``t`` is written (or
    dropped) in cycle ``t + 1`` and, if the FIFO was empty, is on ``output`` from cycle
    ``t + 4``.

    Parameters
    ----------
    depth : int
        Capacity in events, at least 4 (with 3, the queue behind the two registers would
        refuse an event while they are still empty).
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
        if not isinstance(depth, int) or depth < 4:
            raise ValueError(f"FIFO depth must be an integer of at least 4, not {depth!r}")
        if not isinstance(counter_width, int) or not 1 <= counter_width <= 64:
            raise ValueError(f"Counter width must be an integer from 1 to 64 bits, "
                             f"not {counter_width!r}")
        self.depth = depth
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

        m.submodules.fifo = queue = fifo.SyncFIFOBuffered(width=EVENT_WIDTH, depth=self.depth - 1)

        # Input register: nothing combinational between the source and the FIFO's write logic
        valid = Signal()
        payload = Signal(EVENT_WIDTH)
        m.d.comb += self.events.ready.eq(1)
        m.d.sync += valid.eq(self.events.valid), payload.eq(self.events.payload)

        # Write side: never stalls
        write = Signal()
        drop = Signal()
        m.d.comb += [
            queue.w_data.eq(payload),
            queue.w_en.eq(valid),
            write.eq(valid & queue.w_rdy),
            drop.eq(valid & ~queue.w_rdy),
        ]

        # Counters
        count_event(m, self.accepted, write, self.clear, self.tally.accepted)
        count_event(m, self.dropped, drop, self.clear, self.tally.dropped)

        # Read side: the queue's output comes straight from its block RAM, slow to output
        # (5.8 ns on the ULX3S), so it goes only into the output register, and the link's
        # logic starts from a register.
        take = Signal()
        m.d.comb += [
            take.eq(~self.output.valid | self.output.ready),
            queue.r_en.eq(take),
            self.level.eq(queue.level + self.output.valid),
        ]
        with m.If(take):
            m.d.sync += [
                self.output.valid.eq(queue.r_rdy),
                self.output.payload.eq(queue.r_data),
            ]

        return m
