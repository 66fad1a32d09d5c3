"""Counter bank: snapshots against strobes counted cycle by cycle in Python; the STATUS
counters' refusals of tally strobes they cannot count."""

import numpy as np
import pytest
from amaranth.hdl import ResetInserter, Signal
from amaranth.lib import data

from fliss.hdl.counters import CounterBank
from fliss.hdl.status import StatusCounters

from simulation import simulate


def run_bank(dut, strobes, captures):
    """Drive the rows of ``strobes`` (bool, one column per counter) in turn, with a capture
    before row ``r`` for each ``r`` in ``captures``; after each snapshot is ready, read it all
    (no strobes meanwhile). Return the rows driven, cycle by cycle, and per snapshot
    ``(capture cycle, captured cycle, ready cycle, values)``."""
    n = dut.count
    driven, snapshots = [], []

    async def testbench(ctx):
        asked = None
        captured = None
        async def tick(row, capture):
            nonlocal asked, captured
            ctx.set(dut.inc, int(sum(int(bit) << k for k, bit in enumerate(row))))
            ctx.set(dut.capture, int(capture))
            if capture and asked is None:
                asked = len(driven)
            if ctx.get(dut.captured):
                assert asked is not None, f"captured in cycle {len(driven)} with none asked"
                captured = (asked, len(driven))
                asked = None
            driven.append(np.asarray(row, dtype=bool))
            await ctx.tick()

        for number, row in enumerate(strobes):
            await tick(row, number in captures)
            if captured is not None and ctx.get(dut.ready):
                ready = len(driven)
                values = []
                for k in range(n):
                    ctx.set(dut.read_addr, k)
                    await tick(np.zeros(n, dtype=bool), False)
                    values.append(ctx.get(dut.read_data))
                snapshots.append((*captured, ready, values))
                captured = None

    simulate(dut, testbench)
    return np.array(driven), snapshots


def check(dut, driven, snapshots):
    top = (1 << dut.width) - 1
    counts = np.minimum(np.cumsum(driven, axis=0, dtype=np.int64), top)
    for asked, captured, ready, values in snapshots:
        assert 1 <= captured - asked <= dut.count, (asked, captured)
        assert ready - captured == dut.count + 2, (captured, ready)
        assert values == counts[captured].tolist(), (asked, captured)


@pytest.mark.parametrize("count, width, density, seed", [
    (17, 32, 0.5, 1),      # the FLISS status counters
    (3, 32, 0.9, 2),       # the smallest bank
    (8, 5, 0.7, 3),        # narrow counters saturate
    (20, 32, 1.0, 4),      # every strobe high in every cycle: pending counts at their maximum
])
def test_snapshots_exact(count, width, density, seed):
    rng = np.random.default_rng(seed)
    strobes = rng.random((600, count)) < density
    captures = set(int(c) for c in rng.choice(500, size=6, replace=False))
    dut = CounterBank(count, width=width)
    driven, snapshots = run_bank(dut, strobes, captures)
    assert len(snapshots) >= 3, "too few snapshots completed"
    check(dut, driven, snapshots)
    if width < 32:
        assert any((1 << width) - 1 in values for *_, values in snapshots), "none saturated"


def test_reset_clears():
    # Counts from before a reset are gone after it; strobes from the cycle after it count.
    bank = CounterBank(4)
    reset = Signal()
    dut = ResetInserter({"sync": reset})(bank)
    got = []

    async def testbench(ctx):
        ctx.set(bank.inc, 0b1111)
        await ctx.tick().repeat(30)
        ctx.set(reset, 1)
        await ctx.tick()
        ctx.set(reset, 0)
        ctx.set(bank.inc, 0b0101)
        ctx.set(bank.capture, 1)
        cycle = 0
        while not ctx.get(bank.captured):
            await ctx.tick()
            cycle += 1
        ctx.set(bank.capture, 0)
        got.append(cycle)
        await ctx.tick().until(bank.ready)
        ctx.set(bank.inc, 0)
        for k in range(4):
            ctx.set(bank.read_addr, k)
            await ctx.tick()
            got.append(ctx.get(bank.read_data))

    simulate(dut, testbench)
    cycle, *values = got
    assert values == [cycle + 1, 0, cycle + 1, 0]


def test_strobes_from_the_first_cycle():
    # Strobes from the very first cycle, through the clearing scan, are all counted.
    dut = CounterBank(5)
    driven, snapshots = run_bank(dut, np.ones((40, 5), dtype=bool), {0})
    assert len(snapshots) == 1
    check(dut, driven, snapshots)
    asked, captured, ready, values = snapshots[0]
    assert values == [captured + 1] * 5


@pytest.mark.parametrize("kwargs, message", [
    (dict(count=2), "Counter count must be an integer of at least 3, not 2"),
    (dict(count=4, width=0), "Counter width must be a positive integer, not 0"),
])
def test_refuses(construction_error, kwargs, message):
    assert construction_error(lambda: CounterBank(**kwargs)) == message


def test_status_counters_refuse_a_strobe_with_no_counter(construction_error):
    tally = Signal(data.StructLayout({"bad_crc": 1, "refused": 1, "dropped_busy": 1}))

    def count(**names):
        return StatusCounters().count(tally, **names)

    assert construction_error(lambda: count(bad_crc="bad_frames")) == \
        "No STATUS counter 'bad_frames' for the tally strobe 'bad_crc'"
    assert construction_error(lambda: count(bad_crc=None, refused=None)) == \
        "No STATUS counter 'dropped_busy' for the tally strobe 'dropped_busy'"
    assert construction_error(lambda: count(dropped_busy=None, accepted="events")) == \
        "No tally strobe 'accepted' to count"
    assert construction_error(lambda: count(dropped_busy=None)) is None


def test_status_levels_are_snapshots():
    # `pulses` and `ivs_used_up` are read as they were when the snapshot was taken (held across
    # the capture, changed at once after it is ready), `running` as 0, and a counter as its
    # strobes counted: every field at its address of STATUS_FIELDS.
    from fliss.hdl.protocol import STATUS_FIELDS
    dut = StatusCounters()
    reads = []

    async def snapshot(ctx, pulses, used_up, strobes):
        ctx.set(dut.pulses, pulses)
        ctx.set(dut.ivs_used_up, used_up)
        ctx.set(dut.strobes.bad_crc, 1)
        for _ in range(strobes):
            await ctx.tick()
        ctx.set(dut.strobes.bad_crc, 0)
        ctx.set(dut.port.capture, 1)
        await ctx.tick()
        ctx.set(dut.port.capture, 0)
        await ctx.tick().until(dut.port.ready)
        ctx.set(dut.pulses, pulses + 1000)         # after the snapshot: not read
        ctx.set(dut.ivs_used_up, 1 - used_up)
        values = {}
        for name in ("running", "pulses", "ivs_used_up", "bad_crc"):
            ctx.set(dut.port.addr, STATUS_FIELDS.index(name))
            await ctx.tick()
            values[name] = ctx.get(dut.port.data)
        reads.append(values)

    async def testbench(ctx):
        await snapshot(ctx, 1234, 1, 3)
        await snapshot(ctx, 77, 0, 2)

    simulate(dut, testbench)
    assert reads == [{"running": 0, "pulses": 1234, "ivs_used_up": 1, "bad_crc": 3},
                     {"running": 0, "pulses": 77, "ivs_used_up": 0, "bad_crc": 5}]
