"""Raw-event FIFO: gateware against the model; drops only when full, every drop counted."""

import numpy as np
import pytest

from fliss.hdl.rawfifo import RawFifo
from fliss.sim.models import rawfifo as model
from fliss.protocol.events import EVENT_DTYPE, pack, unpack

from simulation import simulate


def random_events(rng, count):
    events = np.zeros(count, dtype=EVENT_DTYPE)
    for name, bits in (("timestamp", 13), ("address", 6), ("collision", 1), ("pulse", 32)):
        events[name] = rng.integers(1 << bits, size=count, dtype=np.uint64)
    return events


def bursty(rng, cycles, high, low):
    """Alternating stretches with probability ``high`` and ``low`` of a one."""
    out = np.zeros(cycles, dtype=bool)
    cycle = 0
    while cycle < cycles:
        n = int(rng.integers(10, 120))
        out[cycle:cycle + n] = rng.random(min(n, cycles - cycle)) < rng.choice([high, low])
        cycle += n
    return out


def run_fifo(dut, valid, ready, words):
    transfers, levels, counters = [], [], {}

    async def testbench(ctx):
        number = 0
        for cycle in range(len(ready)):
            v = cycle < len(valid) and valid[cycle]
            ctx.set(dut.events.valid, int(v))
            if v:
                ctx.set(dut.events.payload.as_value(), int(words[number]))
                number += 1
            ctx.set(dut.output.ready, int(ready[cycle]))
            _, _, out_valid, payload, level, in_ready = await ctx.tick().sample(
                dut.output.valid, dut.output.payload.as_value(), dut.level, dut.events.ready)
            assert in_ready == 1
            levels.append(level)
            if out_valid and ready[cycle]:
                transfers.append((cycle, payload))
        counters.update(accepted=ctx.get(dut.accepted), dropped=ctx.get(dut.dropped))

    simulate(dut, testbench)
    return transfers, np.array(levels), counters


@pytest.mark.parametrize("depth, counter_width", [(16, 32), (5, 32), (4, 32), (16, 4)])
def test_fifo_matches_model(depth, counter_width):
    rng = np.random.default_rng(depth * 100 + counter_width)
    cycles = 3_000
    valid = bursty(rng, cycles, 0.95, 0.2)
    ready = np.concatenate([bursty(rng, cycles, 0.9, 0.1), np.ones(depth + 10, dtype=bool)])
    events = random_events(rng, int(valid.sum()))
    words = pack(events)
    dut = RawFifo(depth=depth, counter_width=counter_width)
    transfers, levels, counters = run_fifo(dut, valid, ready, words)

    want, dropped, want_levels, want_counters = model.simulate(valid, ready, depth=depth,
                                                               counter_width=counter_width)
    assert counters == want_counters
    np.testing.assert_array_equal(levels, want_levels)
    assert [c for c, _ in transfers] == list(want[:, 0])
    np.testing.assert_array_equal(unpack([p for _, p in transfers]), events[want[:, 1]])

    # Independent of the model: nothing lost silently, order kept, drops only when full.
    assert len(transfers) + len(dropped) == len(events)
    kept = np.setdiff1d(np.arange(len(events)), dropped)
    np.testing.assert_array_equal(want[:, 1], kept)
    drop_cycles = np.flatnonzero(valid)[dropped] + 1     # decided after the input register
    assert np.all(levels[drop_cycles] == depth)
    assert len(dropped) > 100
    if counter_width == 4:
        assert counters == {"accepted": 15, "dropped": 15}


def test_clear_counters():
    dut = RawFifo(depth=4)

    async def testbench(ctx):
        ctx.set(dut.events.valid, 1)
        await ctx.tick().repeat(10)            # 9 events past the input register: 4 fit
        assert (ctx.get(dut.accepted), ctx.get(dut.dropped)) == (4, 5)
        ctx.set(dut.clear, 1)
        await ctx.tick()                       # the drop of the clear cycle still counts
        ctx.set(dut.clear, 0)
        assert (ctx.get(dut.accepted), ctx.get(dut.dropped)) == (0, 1)
        await ctx.tick().repeat(3)
        assert ctx.get(dut.dropped) == 4

    simulate(dut, testbench)


@pytest.mark.parametrize("kwargs, message", [
    ({"depth": 3}, "FIFO depth must be an integer from 4 to 1026, not 3"),
    ({"depth": 1027}, "FIFO depth must be an integer from 4 to 1026, not 1027"),
    ({"depth": 8.0}, "FIFO depth must be an integer from 4 to 1026, not 8.0"),
    ({"counter_width": 0}, "Counter width must be an integer from 1 to 64 bits, not 0"),
])
def test_bad_parameters(kwargs, message, construction_error):
    assert construction_error(lambda: RawFifo(**kwargs)) == message
    if "depth" in kwargs:
        with pytest.raises(ValueError) as info:
            model.check_depth(kwargs["depth"])
        assert str(info.value) == message
