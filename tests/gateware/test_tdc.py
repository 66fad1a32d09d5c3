"""TDC interface and coarse TDC: gateware against the model, event by event, counter by counter."""

import numpy as np
import pytest
from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from fliss.hdl.event import Event
from fliss.hdl.tdc import (Gate, EventFilter, TdcInterface, CoarseTdc, SYNC_STAGES, CAPTURE_LATENCY,
                           OUTPUT_LATENCY, MAX_TIMESTAMP, COUNTER_WIDTH)
from fliss.sim.models import tdc as model
from fliss.protocol.events import EVENT_DTYPE, unpack
from simulation import simulate


class FilterOutside(wiring.Component):
    """A capture block built with ``filtered=False`` and an :class:`EventFilter` after it, as
    the top level uses them: it must behave exactly as the block with its own filter."""

    def __init__(self, block):
        self.block = block
        members = {name: member for name, member in block.signature.members.items()
                   if name != "captures"}
        members.update({
            "gate":       In(Gate, init={"end": MAX_TIMESTAMP}),
            "clear":      In(1),
            "events":     Out(stream.Signature(Event)),
        })
        members.update({name: Out(COUNTER_WIDTH) for name in model.COUNTERS})
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        m.submodules.block = self.block
        m.submodules.filter = event_filter = EventFilter()
        for name in self.block.signature.members:
            if name != "captures":
                m.d.comb += getattr(self.block, name).eq(getattr(self, name))
        m.d.comb += [
            event_filter.captures.eq(self.block.captures),
            event_filter.gate.eq(self.gate),
            event_filter.clear.eq(self.clear),
        ]
        m.d.comb += [getattr(self, name).eq(getattr(event_filter, name))
                     for name in model.COUNTERS]
        wiring.connect(m, wiring.flipped(self.events), event_filter.events)
        return m


def make(block_class, filtered):
    return block_class() if filtered else FilterOutside(block_class(filtered=False))


def strobe_train(rng, count, start, *, max_gap=20):
    """First-high cycle and length of each strobe: high 2..4 cycles, low at least 2."""
    rises, highs = [], []
    cycle = start
    for _ in range(count):
        high = int(rng.integers(2, 5))
        rises.append(cycle)
        highs.append(high)
        cycle += high + 2 + int(rng.integers(0, max_gap))
    return np.array(rises), np.array(highs), cycle


def pulse_counter(rng, cycles, *, mean_period=60):
    """Per-cycle ``pulse_index`` (pulses fired so far) and the cycles where it steps."""
    starts = np.cumsum(rng.integers(mean_period // 2, 3 * mean_period // 2, size=cycles))
    starts = starts[starts < cycles] + 5
    index = np.zeros(cycles + 100, dtype=np.int64)
    for s in starts:
        index[s:] += 1
    return index, starts


def ready_pattern(rng, cycles):
    """``events.ready``: mostly high, with a few long stalls that cause overruns."""
    ready = rng.random(cycles + 100) < 0.8
    for start in rng.integers(cycles, size=cycles // 200):
        ready[start:start + int(rng.integers(10, 60))] = False
    return ready


def run(dut, cycles, drive, ready):
    """Apply ``drive(ctx, cycle)`` each cycle and collect (cycle, event) transfers."""
    transfers = []
    counters = {}

    async def testbench(ctx):
        for cycle in range(cycles):
            drive(ctx, cycle)
            ctx.set(dut.events.ready, int(ready[cycle]))
            _, _, valid, payload = await ctx.tick().sample(dut.events.valid,
                                                           dut.events.payload.as_value())
            if valid and ready[cycle]:
                transfers.append((cycle, payload))
        for name in model.COUNTERS:
            counters[name] = ctx.get(getattr(dut, name))

    simulate(dut, testbench)
    cycles_out = np.array([c for c, _ in transfers], dtype=np.int64)
    events_out = unpack([p for _, p in transfers]) if transfers else np.zeros(0, EVENT_DTYPE)
    return cycles_out, events_out, counters


@pytest.mark.parametrize("drop_collisions", [0, 1])
@pytest.mark.parametrize("filtered", [True, False])
def test_tdc_interface_matches_model(filtered, drop_collisions):
    rng = np.random.default_rng(6)
    rises, highs, end = strobe_train(rng, 300, 10)
    cycles = end + 20
    timestamps = rng.integers(8192, size=len(rises))
    addresses = rng.integers(64, size=len(rises))
    collisions = rng.integers(2, size=len(rises))
    pulse_index, _ = pulse_counter(rng, cycles)
    enable = np.zeros(cycles + 100, dtype=bool)
    enable[40:cycles // 2] = True
    enable[cycles // 2 + 300:] = True
    ready = ready_pattern(rng, cycles)
    gate_start, gate_end = 700, 7300

    # Pin waveforms: the bus carries the event only in the SYNC_STAGES + 1 cycles from its
    # strobe's rise (the documented hold time), garbage otherwise: a late capture would show.
    pin_valid = np.zeros(cycles, dtype=bool)
    bus = rng.integers(1 << 20, size=(cycles, 3)) % [8192, 64, 2]
    for rise, high, ts, addr, col in zip(rises, highs, timestamps, addresses, collisions):
        pin_valid[rise:rise + high] = True
        bus[rise:rise + SYNC_STAGES + 1] = ts, addr, col

    dut = make(TdcInterface, filtered)

    def drive(ctx, cycle):
        if cycle == 0:
            ctx.set(dut.gate.start, gate_start)
            ctx.set(dut.gate.end, gate_end)
            ctx.set(dut.gate.drop_collisions, drop_collisions)
        ctx.set(dut.pin_valid, int(pin_valid[cycle]))
        ctx.set(dut.pin_timestamp, int(bus[cycle, 0]))
        ctx.set(dut.pin_address, int(bus[cycle, 1]))
        ctx.set(dut.pin_collision, int(bus[cycle, 2]))
        ctx.set(dut.enable, int(enable[cycle]))
        ctx.set(dut.pulse_index, int(pulse_index[cycle]))

    got_cycles, got, counters = run(dut, cycles, drive, ready)
    want, valid_cycles, want_cycles, want_counters = model.interface(
        rises, timestamps, addresses, collisions, enable=enable, pulse_index=pulse_index,
        gate_start=gate_start, gate_end=gate_end, drop_collisions=drop_collisions, ready=ready)
    assert counters == want_counters, want_counters
    assert all(want_counters[name] > 10 for name in
               ("dropped_stopped", "dropped_gate", "dropped_overrun"))
    assert want_counters["accepted"] > 100
    # with drop_collisions, no flagged event passes and (one in two being flagged) many are
    # counted; without, flagged events pass
    assert np.any(got["collision"] == 1) != bool(drop_collisions)
    assert (want_counters["dropped_collision"] > 30) == bool(drop_collisions)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(got_cycles, want_cycles)
    # Latency as documented: valid from OUTPUT_LATENCY cycles after the strobe reads high.
    first = np.flatnonzero(enable[rises + CAPTURE_LATENCY] & (timestamps >= gate_start) &
                           (timestamps <= gate_end))[0]
    assert valid_cycles[0] == rises[first] + OUTPUT_LATENCY


@pytest.mark.parametrize("filtered", [True, False])
def test_coarse_tdc_matches_model(filtered):
    rng = np.random.default_rng(11)
    # Hits and starts; then no start for 8300 cycles, so hits more than 8191 cycles after the
    # last start overflow; then hits and starts again.
    hits_a, highs_a, end_a = strobe_train(rng, 120, 3, max_gap=12)
    starts_a = 5 + np.cumsum(rng.integers(25, 75, size=200))
    starts_a = starts_a[starts_a < end_a]
    last = int(starts_a[-1])
    hits_b, highs_b, end_b = strobe_train(rng, 40, last + 8100, max_gap=3)
    starts_b = last + 8300 + np.cumsum(rng.integers(25, 75, size=400))
    hits_c, highs_c, end = strobe_train(rng, 120, end_b, max_gap=12)
    starts_b = starts_b[starts_b < end]
    hits = np.concatenate([hits_a, hits_b, hits_c])
    highs = np.concatenate([highs_a, highs_b, highs_c])
    starts = np.concatenate([starts_a, starts_b])
    cycles = end + 20
    pulse_index = np.searchsorted(starts, np.arange(cycles + 100), side="right")
    enable = np.ones(cycles + 100, dtype=bool)
    enable[end_a // 2:end_a // 2 + 150] = False
    ready = ready_pattern(rng, cycles)
    gate_start, gate_end = 3, 45

    pin_hit = np.zeros(cycles, dtype=bool)
    for hit, high in zip(hits, highs):
        pin_hit[hit:hit + high] = True
    tdc_start = np.zeros(cycles, dtype=bool)
    tdc_start[starts[starts < cycles]] = True

    dut = make(CoarseTdc, filtered)

    def drive(ctx, cycle):
        if cycle == 0:
            ctx.set(dut.gate.start, gate_start)
            ctx.set(dut.gate.end, gate_end)
            ctx.set(dut.address, 42)
        ctx.set(dut.pin_hit, int(pin_hit[cycle]))
        ctx.set(dut.tdc_start, int(tdc_start[cycle]))
        ctx.set(dut.enable, int(enable[cycle]))
        ctx.set(dut.pulse_index, int(pulse_index[cycle]))

    got_cycles, got, counters = run(dut, cycles, drive, ready)
    want, _, want_cycles, want_counters = model.coarse(
        hits, starts, enable=enable, pulse_index=pulse_index, address=42,
        gate_start=gate_start, gate_end=gate_end, ready=ready)
    assert counters == want_counters
    assert all(want_counters[name] > 5 for name in model.COUNTERS
               if name != "dropped_collision")
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(got_cycles, want_cycles)
    for event in got[:50]:
        assert event["address"] == 42 and event["collision"] == 0
        assert gate_start <= event["timestamp"] <= gate_end


def test_pulse_index_before_first_pulse():
    # pulse = pulse_index - 1: all ones before the first pulse, 0 after it
    events, _, _, _ = model.interface([0, 10], [5, 6], [1, 2], [0, 1], enable=1,
                                      pulse_index=lambda cycle: int(cycle >= 10))
    assert list(events["pulse"]) == [(1 << 32) - 1, 0]
    dut = TdcInterface()
    got = []

    async def testbench(ctx):
        ctx.set(dut.enable, 1)
        ctx.set(dut.events.ready, 1)
        for cycle in range(25):
            ctx.set(dut.pulse_index, int(cycle >= 10))
            ctx.set(dut.pin_valid, int(cycle in (0, 1, 10, 11)))
            ctx.set(dut.pin_timestamp, 5 if cycle < 10 else 6)
            _, _, valid, pulse = await ctx.tick().sample(dut.events.valid,
                                                         dut.events.payload.pulse)
            if valid:
                got.append((cycle, pulse))

    simulate(dut, testbench)
    assert got == [(OUTPUT_LATENCY, (1 << 32) - 1), (10 + OUTPUT_LATENCY, 0)]


def test_coarse_timestamp_by_hand():
    # start in cycle 10; hits whose pin first reads high in cycles 10, 14 and 40 read 0, 4, 30;
    # a hit in cycle 9 comes before every start and overflows.
    events, _, _, counters = model.coarse([9, 10, 14, 40], [10], enable=1, pulse_index=1)
    assert list(events["timestamp"]) == [0, 4, 30]
    assert list(events["pulse"]) == [0, 0, 0]
    assert counters["dropped_overflow"] == 1 and counters["accepted"] == 3

    dut = CoarseTdc()
    got = []

    async def testbench(ctx):
        ctx.set(dut.enable, 1)
        ctx.set(dut.events.ready, 1)
        for cycle in range(60):
            ctx.set(dut.tdc_start, int(cycle == 10))
            ctx.set(dut.pulse_index, int(cycle >= 10))
            ctx.set(dut.pin_hit, int(cycle in (9, 10, 14, 15, 40, 41)))
            _, _, valid, ts = await ctx.tick().sample(dut.events.valid,
                                                      dut.events.payload.timestamp)
            if valid:
                got.append((cycle, ts))
        assert ctx.get(dut.dropped_overflow) == 1

    simulate(dut, testbench)
    # hits in 9 and 10 merge into one rising edge at 9 (overflow); then 14 and 40
    assert got == [(14 + OUTPUT_LATENCY, 4), (40 + OUTPUT_LATENCY, 30)]


@pytest.mark.parametrize("gate, message", [
    ((0, 8192), "Gate end must be a timestamp code from 0 to 8191, not 8192"),
    ((-1, 10), "Gate start must be a timestamp code from 0 to 8191, not -1"),
    ((20, 10), "Gate start (20) must not be after gate end (10)"),
])
def test_bad_gate(gate, message):
    with pytest.raises(ValueError) as info:
        model.check_gate(*gate)
    assert str(info.value) == message


def test_bad_address():
    with pytest.raises(ValueError) as info:
        model.coarse([1], [0], enable=1, pulse_index=0, address=64)
    assert str(info.value) == "Pixel address must be from 0 to 63, not 64"
