"""Aggressor emitter: against the scheduler model with a shifted enable, and against the victim."""

import gc
import warnings

import numpy as np
import pytest
from amaranth.hdl import Module, Elaboratable, UnusedElaboratable

from fliss.hdl.delay.aggressor import Aggressor
from fliss.hdl.delay.core import DelayCore
from fliss.hdl.delay.source import DelayMode
from fliss.sim.models import aggressor as model
from fliss.sim.models.scheduler import Settings
from simulation import simulate


def apply(ctx, dut, settings, offset=None):
    if offset is not None:
        ctx.set(dut.emitter.offset, offset)
    ctx.set(dut.settings.period, settings.period)
    ctx.set(dut.settings.grid, int(settings.grid))
    ctx.set(dut.settings.pulse_width, settings.pulse_width)
    if dut.delay_source:
        ctx.set(dut.settings.mode, settings.mode)
        ctx.set(dut.settings.length, settings.length)
        ctx.set(dut.settings.mask_width, settings.mask_width)
        ctx.set(dut.settings.seed, settings.seed)


def record(dut, cycles, script):
    """Run ``script(ctx, cycle)`` before each cycle; return per-cycle ``fire`` and ``laser``."""
    fire = np.zeros(cycles, dtype=bool)
    laser = np.zeros(cycles, dtype=bool)

    async def testbench(ctx):
        for cycle in range(cycles):
            script(ctx, cycle)
            _, _, fire[cycle], laser[cycle] = await ctx.tick().sample(dut.fire, dut.laser)

    simulate(dut, testbench)
    return fire, laser


CASES = [
    (True, Settings(mode=DelayMode.MSEQ, length=5, seed=3, period=40, pulse_width=3),
     Settings(mode=DelayMode.MSEQ, length=6, seed=17, period=55, pulse_width=2)),
    (True, Settings(mode=DelayMode.MASKED, mask_width=4, seed=0xACE1, period=30, grid=True,
                    pulse_width=4),
     Settings(mode=DelayMode.MASKED, mask_width=3, seed=99, period=25, grid=False,
              pulse_width=1)),
    (False, Settings(period=37, pulse_width=5), Settings(period=20, pulse_width=19)),
]


@pytest.mark.parametrize("delay_source, first, second", CASES)
def test_matches_model(delay_source, first, second):
    enable, offset, update, disable, cycles = 4, 13, 1_211, 2_400, 2_500
    dut = Aggressor(delay_source=delay_source)

    def script(ctx, cycle):
        if cycle == 0:
            apply(ctx, dut, first, offset)
        if cycle == enable:
            ctx.set(dut.enable, 1)
        if cycle == update:
            apply(ctx, dut, second)
            ctx.set(dut.update, 1)
        if cycle == update + 1:
            ctx.set(dut.update, 0)
        if cycle == disable:
            ctx.set(dut.enable, 0)

    fire, laser = record(dut, cycles, script)
    pulses = model.simulate(first, cycles - 1, offset=offset, enable=enable, disable=disable,
                            updates=[(update, second)])
    assert len(pulses) > 30
    np.testing.assert_array_equal(np.flatnonzero(fire), [p[0] for p in pulses])
    np.testing.assert_array_equal(laser, model.laser_waveform(pulses, cycles))
    # nothing fires before the offset has elapsed
    assert np.flatnonzero(fire)[0] >= enable + offset + 2


@pytest.mark.parametrize("switch", ["enable", "emitter.enable"])
def test_offset_restarts_with_enable(switch):
    # The aggressor runs while both `enable` (the victim's) and its own `emitter.enable` (the
    # `aggressor` register) are high: switching either one restarts the offset.
    settings = Settings(mode=DelayMode.MSEQ, length=4, seed=5, period=30, pulse_width=2)
    dut = Aggressor()
    offset, cycles = 21, 900
    segments = [(3, 300), (310, 320), (500, None)]   # the second is shorter than the offset
    signal, other = ((dut.enable, dut.emitter.enable) if switch == "enable" else
                     (dut.emitter.enable, dut.enable))

    def script(ctx, cycle):
        if cycle == 0:
            apply(ctx, dut, settings, offset)
            ctx.set(signal, 0)
            ctx.set(other, 1)
        for on, off in segments:
            if cycle == on:
                ctx.set(signal, 1)
            if cycle == off:
                ctx.set(signal, 0)

    fire, laser = record(dut, cycles, script)
    pulses = []
    for on, off in segments:
        pulses += model.simulate(settings, cycles - 1, offset=offset, enable=on, disable=off)
    np.testing.assert_array_equal(np.flatnonzero(fire), [p[0] for p in pulses])
    np.testing.assert_array_equal(laser, model.laser_waveform(pulses, cycles))


class _Bench(Elaboratable):
    """Victim delay core and aggressor on one clock, as on the paper's FPGA."""
    def __init__(self):
        self.victim = DelayCore()
        self.aggressor = Aggressor()

    def elaborate(self, platform):
        m = Module()
        m.submodules.victim = self.victim
        m.submodules.aggressor = self.aggressor
        return m


def test_paper_bench_offset():
    # Same PRF, no delay on either side: every aggressor pulse rises 75 ns = 6 cycles after the
    # victim's. Worked out from the waveforms, not from the model.
    offset = model.offset_cycles()
    assert offset == 6
    bench = _Bench()
    victim, aggressor = bench.victim, bench.aggressor
    cycles = 1_000
    rises = {"victim": [], "aggressor": []}

    async def testbench(ctx):
        for dut in (victim, aggressor):
            ctx.set(dut.settings.period, 80)
            ctx.set(dut.settings.pulse_width, 2)
        ctx.set(aggressor.emitter.offset, offset)
        await ctx.tick()
        ctx.set(victim.enable, 1)           # in cycle 1, as a register file would
        ctx.set(aggressor.enable, 1)
        last = {"victim": 0, "aggressor": 0}
        for cycle in range(cycles):
            _, _, v, a = await ctx.tick().sample(victim.laser, aggressor.laser)
            for name, value in (("victim", v), ("aggressor", a)):
                if value and not last[name]:
                    rises[name].append(cycle)
                last[name] = value

    simulate(bench, testbench)
    victim_rises = np.array(rises["victim"])
    aggressor_rises = np.array(rises["aggressor"])
    # enable in cycle 1: first take in 2, fire in 3, laser up in 4 (loop cycle 3)
    np.testing.assert_array_equal(victim_rises, 3 + 80 * np.arange(13))
    np.testing.assert_array_equal(aggressor_rises, victim_rises + offset)


def test_bad_parameters():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnusedElaboratable)
        with pytest.raises(TypeError) as info:
            Aggressor(delay_source=1)
        message = str(info.value)
        del info
        gc.collect()
    assert message == "delay_source must be True or False, not 1"
    with pytest.raises(ValueError) as info:
        model.simulate(Settings(), 10, offset=-1)
    assert str(info.value) == "Aggressor offset must be from 0 to 4294967295 clock cycles, not -1"
    with pytest.raises(ValueError) as info:
        model.offset_cycles(-75e-9)
    assert str(info.value) == "Aggressor offset must be zero or positive, not -7.5e-08 s"
