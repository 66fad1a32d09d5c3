"""Stream register slice: every transfer comes out once, in order, at full rate (or one every
two cycles at half rate), and its ``ready`` and outputs are registered."""

import numpy as np
import pytest

from fliss.hdl.link.buffer import StreamBuffer

from simulation import simulate


def run_buffer(valid, ready, full_rate=True):
    """Drive ``i`` with a counter on the cycles where ``valid`` is set (holding it until it is
    taken, as a stream source must) and ``o.ready`` from ``ready``. Returns the payloads that
    left, the cycle of each input and output transfer, and ``i.ready`` per cycle."""
    dut = StreamBuffer(16, full_rate=full_rate)
    taken_in, taken_out, out, ready_in = [], [], [], []

    async def testbench(ctx):
        value, holding = 0, False
        for cycle in range(len(ready)):
            holding = holding or bool(valid[cycle])
            ctx.set(dut.i.valid, int(holding))
            ctx.set(dut.i.payload, value)
            ctx.set(dut.o.ready, int(ready[cycle]))
            i_ready = ctx.get(dut.i.ready)
            ready_in.append(i_ready)
            if holding and i_ready:
                taken_in.append(cycle)
                value, holding = value + 1, False
            if ctx.get(dut.o.valid) and ready[cycle]:
                taken_out.append(cycle)
                out.append(ctx.get(dut.o.payload))
            await ctx.tick()

    simulate(dut, testbench)
    return out, taken_in, taken_out, ready_in


@pytest.mark.parametrize("full_rate", [True, False])
@pytest.mark.parametrize("p_valid,p_ready", [(1.0, 1.0), (0.5, 1.0), (1.0, 0.5), (0.7, 0.3),
                                             (0.3, 0.9)])
def test_order_and_nothing_lost(p_valid, p_ready, full_rate):
    rng = np.random.default_rng(int(p_valid * 10 + p_ready * 100))
    cycles = 2000
    valid = rng.random(cycles) < p_valid
    ready = np.concatenate([rng.random(cycles) < p_ready, np.ones(8, bool)])
    valid = np.concatenate([valid, np.zeros(8, bool)])
    out, taken_in, taken_out, _ = run_buffer(valid, ready, full_rate)
    assert out == list(range(len(taken_in)))
    # every payload leaves after the cycle it entered in
    assert all(t_out > t_in for t_in, t_out in zip(taken_in, taken_out))


def test_full_rate():
    cycles = 500
    out, taken_in, taken_out, ready_in = run_buffer(np.ones(cycles, bool), np.ones(cycles, bool))
    # one transfer per cycle in and out, one cycle of latency
    assert taken_in == list(range(cycles))
    assert taken_out == list(range(1, cycles))


def test_half_rate():
    cycles = 500
    out, taken_in, taken_out, ready_in = run_buffer(np.ones(cycles, bool), np.ones(cycles, bool),
                                                    full_rate=False)
    # one transfer every other cycle in and out, one cycle of latency
    assert taken_in == list(range(0, cycles, 2))
    assert taken_out == list(range(1, cycles, 2))
    assert out == list(range(len(taken_out)))


def test_stall_is_absorbed():
    # The consumer stalls every third cycle: the producer is stopped only by the skid register
    # filling, never in the cycle the stall starts (i.ready is a register).
    cycles = 600
    ready = np.arange(cycles) % 3 != 0
    out, taken_in, taken_out, ready_in = run_buffer(np.ones(cycles, bool), ready)
    assert out == list(range(len(out)))
    assert len(taken_out) == int(ready[1:].sum())
    assert len(taken_in) - len(taken_out) <= 2


def test_bad_full_rate(construction_error):
    assert construction_error(lambda: StreamBuffer(8, full_rate=1), TypeError) == \
        "full_rate must be True or False, not 1"
