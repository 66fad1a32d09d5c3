"""Event counters: one saturating counter in flip-flops (:func:`count_event`), and a bank of many
in block RAM with an exact snapshot (:class:`CounterBank`)."""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out


__all__ = ["count_event", "CounterBank"]


def count_event(m, counter, condition, clear, strobe=None):
    """Saturating event counter: ``counter`` counts the cycles with ``condition``, up to all
    ones. ``clear`` restarts it from the event of its own cycle (0 or 1), so no event goes
    uncounted. A register remembers that it is full, so no wide comparator sits in its enable
    path. ``strobe``, if given, is driven with ``condition``: the same events, for a counter
    elsewhere (a :class:`~fliss.hdl.counters.CounterBank`)."""
    if strobe is not None:
        m.d.comb += strobe.eq(condition)
    top = (1 << len(counter)) - 1
    full = Signal(name=f"{counter.name}_full")
    with m.If(clear):
        m.d.sync += counter.eq(condition), full.eq(condition & (top == 1))
    with m.Elif(condition & ~full):
        m.d.sync += counter.eq(counter + 1), full.eq(counter == top - 1)


class CounterBank(wiring.Component):
    """``count`` saturating counters of ``width`` bits, kept in block RAM.

    A counter in flip-flops costs a logic cell per bit, and a snapshot of it another; on an
    iCE40UP5K the status counters alone would fill a fifth of the chip. Here each counter has a
    small pending count in logic, and the full counts live in a memory that a scan brings up to
    date, one counter per cycle:

    * every ``count`` cycles (a *handoff*), all pending counts move at once into a shift
      register and restart from zero;
    * in each of the next ``count`` cycles, the scan reads one counter from the memory, adds
      the pending count that the shift register brings out for it, and writes it back (clamped
      to all ones), so counter ``k`` is written back ``k + 2`` cycles after the handoff.

    A pending count never exceeds ``count``, so no event is lost however many strobes arrive.

    A snapshot takes the counts *at a handoff*: the scan after it writes every sum to a second
    memory too, which the reader reads at leisure. The snapshot is exact: counter ``k`` in it
    is the number of strobes on ``inc[k]`` up to and including the cycle of the handoff
    (``captured``), clamped to all ones. ``captured`` is the first handoff after the cycle of
    ``capture``, 1 to ``count`` cycles later; ``ready`` rises once the snapshot
    is complete, ``count + 2`` cycles after ``captured``.

    Reset zeroes the counters: the first scan after it writes zeros.

    Parameters
    ----------
    count : int
        Number of counters, at least 3.
    width : int
        Width of each counter.

    Members
    -------
    inc : In(count)
        One strobe per counter: each cycle it is high counts one.
    capture : In(1)
        Take a snapshot.
    captured : Out(1)
        The cycle whose counts the snapshot taken next holds.
    ready : Out(1)
        No snapshot is being taken: the snapshot memory holds the last one (zeros after
        configuration; a reset leaves it as it was).
    read_addr : In(range(count))
    read_data : Out(width)
        Counter ``read_addr`` of the snapshot, one cycle later.
    """

    def __init__(self, count, *, width=32):
        if not isinstance(count, int) or count < 3:
            raise ValueError(f"Counter count must be an integer of at least 3, not {count!r}")
        if not isinstance(width, int) or width < 1:
            raise ValueError(f"Counter width must be a positive integer, not {width!r}")
        self.count = count
        self.width = width
        super().__init__({
            "inc":       In(count),
            "capture":   In(1),
            "captured":  Out(1),
            "ready":     Out(1),
            "read_addr": In(range(count)),
            "read_data": Out(width),
        })

    def elaborate(self, platform):
        m = Module()
        n = self.count

        m.submodules.live = live = Memory(shape=self.width, depth=n, init=[])
        m.submodules.snap = snap = Memory(shape=self.width, depth=n, init=[])
        live_rd = live.read_port()
        live_wr = live.write_port()
        snap_rd = snap.read_port()
        snap_wr = snap.write_port()
        m.d.comb += [
            snap_rd.addr.eq(self.read_addr),
            self.read_data.eq(snap_rd.data),
        ]

        # Scan position and handoff
        position = Signal(range(n))
        handoff = Signal()
        m.d.comb += handoff.eq(position == n - 1)
        m.d.sync += position.eq(Mux(handoff, 0, position + 1))

        # Pending counts, and the shift register that brings them to the scan in turn
        pending = [Signal(range(n + 1), name=f"pending{k}") for k in range(n)]
        queue = [Signal(range(n + 1), name=f"queue{k}") for k in range(n)]
        for k in range(n):
            with m.If(handoff):
                m.d.sync += [queue[k].eq(pending[k] + self.inc[k]), pending[k].eq(0)]
            with m.Else():
                m.d.sync += pending[k].eq(pending[k] + self.inc[k])
                m.d.sync += queue[k].eq(queue[k + 1] if k + 1 < n else 0)

        # Snapshot: asked for (registered: `capture` comes from a command's decoding, and
        # `captured` enables many registers elsewhere), then taken during the scan after a
        # handoff
        asked = Signal()
        copying = Signal()
        with m.If(handoff):
            m.d.sync += [copying.eq(asked), asked.eq(self.capture)]
        with m.Elif(self.capture):
            m.d.sync += asked.eq(1)
        m.d.comb += self.captured.eq(handoff & asked)

        # Stage 0: read the counter at `position` and take its pending count.
        # Stage 1: write back the sum, clamped (to zero in the first scan after reset).
        clearing = Signal(init=1)
        with m.If(handoff):
            m.d.sync += clearing.eq(0)
        address1 = Signal(range(n))
        pending1 = Signal(range(n + 1))
        copy1 = Signal()
        clear1 = Signal(init=1)     # (in the cycle after reset too: a write of zero to counter 0)
        m.d.comb += live_rd.addr.eq(position)
        m.d.sync += [
            address1.eq(position),
            pending1.eq(queue[0]),
            copy1.eq(copying),
            clear1.eq(clearing),
        ]
        total = Signal(self.width + 1)
        value = Signal(self.width)
        m.d.comb += [
            total.eq(Mux(clear1, 0, live_rd.data) + pending1),
            value.eq(Mux(total[-1], (1 << self.width) - 1, total[:-1])),
            live_wr.addr.eq(address1),
            live_wr.data.eq(value),
            live_wr.en.eq(1),
            snap_wr.addr.eq(address1),
            snap_wr.data.eq(value),
            snap_wr.en.eq(copy1),
        ]
        m.d.comb += self.ready.eq(~asked & ~copying & ~copy1)

        return m
