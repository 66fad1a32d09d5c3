"""Photon event capture: the sensor's TDC interface and a built-in coarse TDC.

Both blocks deliver :class:`~fliss.hdl.event.Event` records on the same kind of stream, through
the same :class:`EventFilter`, so the rest of the design does not care where events come from.
"""

from amaranth.hdl import C, Module, Mux, Signal
from amaranth.lib import cdc, data, stream, wiring
from amaranth.lib.wiring import In, Out

from .counters import count_event
from .event import Event, TIMESTAMP_BITS, ADDRESS_BITS, PULSE_BITS
from .registers import GATE


__all__ = ["SYNC_STAGES", "COUNTER_WIDTH", "CAPTURE_LATENCY", "FILTER_LATENCY", "OUTPUT_LATENCY",
           "MAX_TIMESTAMP", "FILTER_COUNTERS",
           "Gate", "Capture", "EventFilter", "TdcInterface", "CoarseTdc"]


#: Flip-flops of the input synchronisers.
SYNC_STAGES = 2
#: Width of the event counters of the acquisition blocks (saturating): TDC, histogram, raw FIFO.
COUNTER_WIDTH = 32
#: Cycles from the first cycle a strobe (or hit) pin is high to the cycle the edge is detected,
#: in which the bus, ``enable`` and ``pulse_index`` are sampled.
CAPTURE_LATENCY = SYNC_STAGES
#: Cycles from the :class:`EventFilter` ``capture`` strobe to ``events.valid``.
FILTER_LATENCY = 2
#: Cycles from the first cycle a strobe (or hit) pin is high to ``events.valid``.
OUTPUT_LATENCY = CAPTURE_LATENCY + 1 + FILTER_LATENCY
#: Largest timestamp code.
MAX_TIMESTAMP = (1 << TIMESTAMP_BITS) - 1
#: The counters of an :class:`EventFilter`, in its order of precedence (``accepted`` first).
FILTER_COUNTERS = ("accepted", "dropped_stopped", "dropped_overflow", "dropped_collision",
                   "dropped_gate", "dropped_overrun")

#: The gate of an :class:`EventFilter`: ``start`` and ``end`` in timestamp codes, inclusive, and
#: ``drop_collisions`` (the register group :data:`~fliss.hdl.registers.GATE`).
Gate = GATE.layout()


def _synchronised_rise(m, pin, name):
    """A one-cycle strobe for each rising edge of the asynchronous ``pin``, after a
    :data:`SYNC_STAGES`-flip-flop synchroniser (submodule ``{name}_sync``)."""
    level = Signal(name=name)
    level_last = Signal(name=f"{name}_last")
    m.submodules[f"{name}_sync"] = cdc.FFSynchronizer(pin, level, stages=SYNC_STAGES)
    m.d.sync += level_last.eq(level)
    rise = Signal(name=f"{name}_rise")
    m.d.comb += rise.eq(level & ~level_last)
    return rise


class Capture(data.Struct):
    """A raw capture of :class:`TdcInterface` or :class:`CoarseTdc`, for an
    :class:`EventFilter`: ``valid`` strobes for one cycle with the event, whether its timestamp
    overflowed, and whether acquisition was enabled. Both blocks give captures in this one
    layout, so one filter can serve either (a multiplexer on the struct selects one)."""
    valid:    1
    event:    Event
    overflow: 1
    enabled:  1


class EventFilter(wiring.Component):
    """Event gate and output register, with drop counters.

    An event presented with ``captures.valid`` is, in this order of precedence, dropped and
    counted in

    * ``dropped_stopped`` if ``captures.enabled`` is low (acquisition stopped);
    * ``dropped_overflow`` if ``captures.overflow`` is high (timestamp beyond 13 bits);
    * ``dropped_collision`` if ``gate.drop_collisions`` is set and the event's ``collision``
      flag is (the sensor flags an event whose timestamp it cannot trust: it is dropped for
      that before its timestamp is compared with the gate);
    * ``dropped_gate`` if its timestamp is outside ``gate.start … gate.end`` (inclusive);
    * ``dropped_overrun`` if the previous event still waits on ``events``;

    and otherwise counted in ``accepted`` and put on ``events``. The classification takes two
    pipeline stages (:data:`FILTER_LATENCY`): an event presented in cycle ``f`` is compared with
    the gate in cycle ``f``, meets the output register (overrun check) in cycle ``f + 1`` and is
    on ``events`` from cycle ``f + 2``. All counters saturate at ``2**32 - 1``; ``clear``
    restarts them (an event counted in the ``clear`` cycle counts as the first).

    Members
    -------
    captures : In(Capture)
        An event (``valid``: in this cycle), whether its timestamp overflowed, and whether
        acquisition is running.
    gate : In(Gate)
        Gate in timestamp codes, ``start … end`` inclusive; by default ``0 … 8191`` (all codes);
        ``drop_collisions``: drop the events flagged as collisions (by default kept). The
        layout of the register group :data:`~fliss.hdl.registers.GATE`.
    clear : In(1)
        Reset the counters.
    events : Out(stream.Signature(Event))
        Accepted events.
    accepted, dropped_stopped, dropped_overflow : Out(32)
    dropped_collision, dropped_gate, dropped_overrun : Out(32)
        Event counters.
    tally : Out(data.StructLayout)
        One strobe per counter, same names: high in each cycle the counter counts (and when it
        is full), for counters elsewhere.
    """

    captures:          In(Capture)
    gate:              In(Gate, init={"end": MAX_TIMESTAMP})
    clear:             In(1)
    events:            Out(stream.Signature(Event))
    accepted:          Out(COUNTER_WIDTH)
    dropped_stopped:   Out(COUNTER_WIDTH)
    dropped_overflow:  Out(COUNTER_WIDTH)
    dropped_collision: Out(COUNTER_WIDTH)
    dropped_gate:      Out(COUNTER_WIDTH)
    dropped_overrun:   Out(COUNTER_WIDTH)
    tally:             Out(data.StructLayout({name: 1 for name in FILTER_COUNTERS}))

    def elaborate(self, platform):
        m = Module()

        # Stage 1: classification, registered
        timestamp = self.captures.event.timestamp
        captured = Signal()
        event = Signal(Event)
        stopped = Signal()
        overflow = Signal()
        collision = Signal()
        outside = Signal()
        m.d.sync += [
            captured.eq(self.captures.valid),
            event.eq(self.captures.event),
            stopped.eq(~self.captures.enabled),
            overflow.eq(self.captures.overflow),
            collision.eq(self.captures.event.collision & self.gate.drop_collisions),
            outside.eq((timestamp < self.gate.start) | (timestamp > self.gate.end)),
        ]

        # Stage 2: output register, counters
        in_gate = Signal()
        overrun = Signal()
        accept = Signal()
        busy = self.events.valid & ~self.events.ready
        m.d.comb += [
            in_gate.eq(captured & ~stopped & ~overflow & ~collision & ~outside),
            overrun.eq(in_gate & busy),
            accept.eq(in_gate & ~busy),
        ]
        t = self.tally
        count_event(m, self.accepted, accept, self.clear, t.accepted)
        count_event(m, self.dropped_stopped, captured & stopped, self.clear, t.dropped_stopped)
        count_event(m, self.dropped_overflow, captured & ~stopped & overflow, self.clear,
                    t.dropped_overflow)
        count_event(m, self.dropped_collision, captured & ~stopped & ~overflow & collision,
                    self.clear, t.dropped_collision)
        count_event(m, self.dropped_gate, captured & ~stopped & ~overflow & ~collision & outside,
                    self.clear, t.dropped_gate)
        count_event(m, self.dropped_overrun, overrun, self.clear, t.dropped_overrun)

        with m.If(self.events.ready):
            m.d.sync += self.events.valid.eq(0)
        with m.If(accept):
            m.d.sync += [
                self.events.valid.eq(1),
                self.events.payload.eq(event),
            ]

        return m


def _filter_ports(component, event_filter):
    """Connections from a capture block's setting ports to its filter."""
    return [
        event_filter.gate.eq(component.gate),
        event_filter.clear.eq(component.clear),
        component.accepted.eq(event_filter.accepted),
        component.dropped_stopped.eq(event_filter.dropped_stopped),
        component.dropped_overflow.eq(event_filter.dropped_overflow),
        component.dropped_collision.eq(event_filter.dropped_collision),
        component.dropped_gate.eq(event_filter.dropped_gate),
        component.dropped_overrun.eq(event_filter.dropped_overrun),
    ]


def _capture_members(filtered, members):
    """The ports of a capture block: ``members`` and either those of its :class:`EventFilter`
    (``filtered``) or a ``captures`` port of :class:`Capture`."""
    members = dict(members)
    if filtered:
        members.update({
            "gate":             In(Gate, init={"end": MAX_TIMESTAMP}),
            "clear":            In(1),
            "events":           Out(stream.Signature(Event)),
            "accepted":         Out(COUNTER_WIDTH),
            "dropped_stopped":  Out(COUNTER_WIDTH),
            "dropped_overflow": Out(COUNTER_WIDTH),
            "dropped_collision": Out(COUNTER_WIDTH),
            "dropped_gate":     Out(COUNTER_WIDTH),
            "dropped_overrun":  Out(COUNTER_WIDTH),
        })
    else:
        members["captures"] = Out(Capture)
    return members


def _filter_or_forward(m, component, capture, event, overflow, enabled):
    """The filter of a capture block, or its raw captures on ``captures``."""
    captures = Signal(Capture)
    fields = {"valid": capture, "event": event, "overflow": overflow, "enabled": enabled}
    m.d.comb += [captures[name].eq(value) for name, value in fields.items()]
    if component.filtered:
        m.submodules.filter = event_filter = EventFilter()
        m.d.comb += [
            event_filter.captures.eq(captures),
            *_filter_ports(component, event_filter),
        ]
        wiring.connect(m, wiring.flipped(component.events), event_filter.events)
    else:
        m.d.comb += component.captures.eq(captures)


class TdcInterface(wiring.Component):
    """Timestamp interface of the sensor's on-chip TDC (Figure 6 of the paper).

    Each rising edge of the sensor's ``pin_valid`` strobe is one photon event: timestamp, pixel
    address and collision flag on the ``pin_*`` bus. The strobe comes from another clock domain;
    it goes through a :data:`SYNC_STAGES`-flip-flop synchroniser, and the bus is sampled in the
    cycle in which the synchronised strobe's rising edge is seen, when it has been stable for at
    least one clock cycle. If the strobe first reads high in cycle ``c``, the bus, ``enable`` and
    ``pulse_index`` are sampled in cycle ``c +`` :data:`CAPTURE_LATENCY`, and the event is on
    ``events`` from cycle ``c +`` :data:`OUTPUT_LATENCY`. Events then go through an
    :class:`EventFilter` (acquisition stopped, gate, overrun).

    Sensor timing requirements: the bus settles before the strobe rises and holds until at least
    ``SYNC_STAGES + 1`` clock periods after it; the strobe stays high for at least 2 clock periods
    and low for at least 2 clock periods, so at most one event every 4 cycles (20 M events/s at
    80 MHz).

    The event's ``pulse`` field is ``pulse_index - 1`` (modulo ``2**32``): with the pulse
    scheduler's ``pulse_index`` (pulses fired so far), the index of the last pulse fired, i.e. the
    laser cycle the photon belongs to; all ones before the first pulse.

    Parameters
    ----------
    filtered : bool
        With its own :class:`EventFilter` (the default), or without: then the raw captures leave
        on ``captures`` for a filter outside, and the filter's ports below are absent.

    Members
    -------
    pin_valid : In(1)
        Sensor's event strobe, asynchronous.
    pin_timestamp : In(13)
        Sensor's timestamp bus.
    pin_address : In(6)
        Sensor's pixel address bus.
    pin_collision : In(1)
        Sensor's collision flag.
    enable : In(1)
        Acquisition is running; events outside are dropped and counted.
    pulse_index : In(32)
        Pulses fired so far (:class:`~fliss.hdl.delay.scheduler.PulseScheduler` ``pulse_index``).
    gate : In(Gate)
        Gate in timestamp codes, ``start … end`` inclusive; by default all codes.
    clear : In(1)
        Reset the counters.
    events : Out(stream.Signature(Event))
        Accepted events.
    accepted, dropped_stopped, dropped_overflow : Out(32)
    dropped_collision, dropped_gate, dropped_overrun : Out(32)
        Event counters (:class:`EventFilter`); ``dropped_overflow`` stays zero here.
    captures : Out(Capture)
        Only with ``filtered=False``: what would go into the filter, in the cycle it would
        (``overflow`` is always low here).
    """

    def __init__(self, *, filtered=True):
        self.filtered = bool(filtered)
        super().__init__(_capture_members(self.filtered, {
            "pin_valid":     In(1),
            "pin_timestamp": In(TIMESTAMP_BITS),
            "pin_address":   In(ADDRESS_BITS),
            "pin_collision": In(1),
            "enable":        In(1),
            "pulse_index":   In(PULSE_BITS),
        }))

    def elaborate(self, platform):
        m = Module()

        # Strobe synchroniser and edge detector
        rise = _synchronised_rise(m, self.pin_valid, "strobe")

        # Capture: the bus has been stable since the strobe rose
        capture = Signal()
        event = Signal(Event)
        enabled = Signal()
        m.d.sync += capture.eq(rise)
        with m.If(rise):
            m.d.sync += [
                event.timestamp.eq(self.pin_timestamp),
                event.address.eq(self.pin_address),
                event.collision.eq(self.pin_collision),
                event.pulse.eq(self.pulse_index - 1),
                enabled.eq(self.enable),
            ]

        _filter_or_forward(m, self, capture, event, C(0), enabled)

        return m


class CoarseTdc(wiring.Component):
    """Coarse TDC: photon hits timestamped in clock cycles from the TDC start.

    For boards without the sensor chip: a photodiode or SPAD module drives ``pin_hit``. Its
    rising edges go through a :data:`SYNC_STAGES`-flip-flop synchroniser; ``tdc_start`` and
    ``pulse_index`` are delayed by the same number of cycles, so a hit whose pin first reads high
    in cycle ``c`` gets the timestamp ``c - s``, where ``s`` is the cycle of the last
    ``tdc_start`` strobe at or before ``c``, and ``pulse`` = ``pulse_index - 1`` as it was in
    cycle ``c`` (see :class:`TdcInterface`). Hits with ``c - s`` above 8191, or before the first
    start, are dropped and counted in ``dropped_overflow``. The event is on ``events`` from cycle
    ``c +`` :data:`OUTPUT_LATENCY`; ``enable`` is sampled in cycle ``c +``
    :data:`CAPTURE_LATENCY`. The hit pin must stay high and low for at least 2 clock periods.

    Parameters
    ----------
    filtered : bool
        As in :class:`TdcInterface`.

    Members
    -------
    pin_hit : In(1)
        Photon hit, asynchronous, active high.
    tdc_start : In(1)
        TDC start strobe (:class:`~fliss.hdl.delay.laser.LaserTrigger` ``tdc_start``).
    pulse_index : In(32)
        Pulses fired so far (:class:`~fliss.hdl.delay.scheduler.PulseScheduler` ``pulse_index``).
    address : In(6)
        Pixel address given to the events.
    enable, gate, clear, events
        As in :class:`TdcInterface`.
    accepted, dropped_stopped, dropped_overflow : Out(32)
    dropped_collision, dropped_gate, dropped_overrun : Out(32)
        Event counters (:class:`EventFilter`); ``dropped_collision`` stays zero here.
    captures : Out(Capture)
        Only with ``filtered=False``, as in :class:`TdcInterface`.
    """

    def __init__(self, *, filtered=True):
        self.filtered = bool(filtered)
        super().__init__(_capture_members(self.filtered, {
            "pin_hit":     In(1),
            "tdc_start":   In(1),
            "pulse_index": In(PULSE_BITS),
            "address":     In(ADDRESS_BITS),
            "enable":      In(1),
        }))

    def elaborate(self, platform):
        m = Module()

        # Hit synchroniser and edge detector
        rise = _synchronised_rise(m, self.pin_hit, "hit")

        # TDC start and pulse index, delayed as much as the hit
        start = self.tdc_start
        pulse = self.pulse_index
        for stage in range(SYNC_STAGES):
            start_next = Signal(name=f"start_{stage + 1}")
            pulse_next = Signal(PULSE_BITS, name=f"pulse_{stage + 1}")
            m.d.sync += start_next.eq(start), pulse_next.eq(pulse)
            start, pulse = start_next, pulse_next

        # Time since the (delayed) start; MAX_TIMESTAMP + 1 means overflowed or never started
        elapsed = Signal(range(MAX_TIMESTAMP + 2), init=MAX_TIMESTAMP + 1)
        now = Signal(range(MAX_TIMESTAMP + 2))
        m.d.comb += now.eq(Mux(start, 0, elapsed))
        with m.If(now != MAX_TIMESTAMP + 1):
            m.d.sync += elapsed.eq(now + 1)
        with m.Else():
            m.d.sync += elapsed.eq(now)

        # Capture
        capture = Signal()
        event = Signal(Event)
        overflow = Signal()
        enabled = Signal()
        m.d.sync += capture.eq(rise)
        with m.If(rise):
            m.d.sync += [
                event.timestamp.eq(now),
                event.address.eq(self.address),
                event.collision.eq(0),
                event.pulse.eq(pulse - 1),
                overflow.eq(now == MAX_TIMESTAMP + 1),
                enabled.eq(self.enable),
            ]

        _filter_or_forward(m, self, capture, event, overflow, enabled)

        return m
