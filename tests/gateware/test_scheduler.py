"""Pulse scheduler, laser trigger and delay core in Amaranth's simulator, against the model."""

import random

import numpy as np
import pytest

from fliss.hdl.clock import period_cycles
from fliss.hdl.delay.core import DelayCore
from fliss.hdl.delay.source import DelayMode
from fliss.hdl.delay.laser import LaserTrigger
from fliss.sim.models.aggressor import laser_waveform
from fliss.sim.models.scheduler import (LATENCY, Settings, check_schedule, fire_cycles, simulate,
                                        start_cycle)
from simulation import simulate as run_simulation


#: The modes with a seed (the keyed mode has its own tests, in test_keyed.py).
SEEDED_MODES = (DelayMode.OFF, DelayMode.MSEQ, DelayMode.MASKED)

FIELDS = ("mode", "length", "mask_width", "seed", "period", "grid", "pulse_width")


def run_core(settings, cycles, *, updates=(), enable=1, disable=None, reset=None, present=(),
             widths=None):
    """Run the delay core; return pulses as (fire, delay, width, index) and the laser trace.
    ``enable`` is the cycle it rises in, or a function of the cycle; ``present`` holds (cycle,
    settings) presented from that cycle on, without an update strobe; ``widths`` are the
    core's ``period_width`` and ``pulse_width_width``."""
    dut = DelayCore(**(widths or {}))
    pulses, laser, starts = [], [], []
    updates = dict(updates)

    async def testbench(ctx):
        for name in FIELDS:
            ctx.set(dut.settings[name], getattr(settings, name))
        for cycle in range(cycles):
            if callable(enable):
                ctx.set(dut.enable, enable(cycle))
            else:
                ctx.set(dut.enable, enable <= cycle and (disable is None or cycle < disable))
            ctx.set(dut.update, cycle in updates)
            for at, presented in present:
                if cycle == at:
                    for name in FIELDS:
                        ctx.set(dut.settings[name], getattr(presented, name))
            if cycle in updates:
                for name in FIELDS:
                    ctx.set(dut.settings[name], getattr(updates[cycle], name))
            if ctx.get(dut.fire):
                pulses.append((cycle, ctx.get(dut.fire_delay), None, ctx.get(dut.pulse_index)))
            laser.append(ctx.get(dut.laser))
            starts.append(ctx.get(dut.tdc_start))
            await ctx.tick()

    run_simulation(dut, testbench, clock_hz=80e6)
    return pulses, np.array(laser), np.array(starts)


def laser_pulses(laser):
    """(rising edge cycle, width) of each laser pulse in a trace."""
    edges = np.diff(np.concatenate(([0], laser, [0])).astype(int))
    rises, falls = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return list(zip(rises.tolist(), (falls - rises).tolist()))


def check_against_model(settings, cycles, *, widths=None, **kwargs):
    kwargs.setdefault("enable", 1)
    pulses, laser, starts = run_core(settings, cycles, widths=widths, **kwargs)
    expected = simulate(settings, cycles - 1 - LATENCY, **kwargs)
    assert [(f, d, i) for f, d, _, i in pulses[:len(expected)]] == \
        [(f, d, i) for f, d, _, i in expected]
    # Laser rises, and the TDC starts, LATENCY cycles after each fire, for the pulse's width.
    assert laser_pulses(laser)[:len(expected)] == [(f + LATENCY, w) for f, _, w, _ in expected]
    assert np.flatnonzero(starts).tolist()[:len(expected)] == \
        [f + LATENCY for f, *_ in expected]
    return expected


@pytest.mark.parametrize("settings", [
    Settings(mode=DelayMode.OFF, period=10, pulse_width=3),
    Settings(mode=DelayMode.MSEQ, length=3, seed=6, period=7, pulse_width=6),
    Settings(mode=DelayMode.MSEQ, length=6, seed=17, period=80, pulse_width=2),
    Settings(mode=DelayMode.MASKED, mask_width=4, seed=0xFEED, period=20, pulse_width=1),
    Settings(mode=DelayMode.MSEQ, length=4, seed=9, period=20, grid=True, pulse_width=5),
    Settings(mode=DelayMode.MASKED, mask_width=3, seed=3, period=9, grid=True, pulse_width=1),
    Settings(mode=DelayMode.OFF, period=2, pulse_width=1),
], ids=lambda s: f"{s.mode.name}-T{s.period}-W{s.pulse_width}-{'grid' if s.grid else 'int'}")
def test_core_against_model(settings):
    settings.check()
    expected = check_against_model(settings, 3000)
    assert len(expected) > 20


@pytest.mark.parametrize("settings", [
    Settings(mode=DelayMode.MSEQ, length=3, seed=5, period=65_541, pulse_width=255),
    Settings(mode=DelayMode.MASKED, mask_width=2, seed=9, period=65_539, grid=True,
             pulse_width=200),
], ids=["interval", "grid"])
def test_narrow_core_against_model(settings):
    # The smallest settings widths: a 17-bit period (its timers' high halves are one bit, and
    # this period uses it) and an 8-bit pulse width at its maximum.
    settings.check()
    expected = check_against_model(settings, 3 * settings.period,
                                   widths=dict(period_width=17, pulse_width_width=8))
    assert len(expected) == 3


@pytest.mark.parametrize("widths, message", [
    (dict(period_width=16), "Period width must be an integer from 17 to 32 bits, not 16"),
    (dict(period_width=33), "Period width must be an integer from 17 to 32 bits, not 33"),
    (dict(pulse_width_width=0), "Pulse width width must be an integer from 1 to 16 bits, not 0"),
    (dict(pulse_width_width=17),
     "Pulse width width must be an integer from 1 to 16 bits, not 17"),
])
def test_core_refuses_widths(construction_error, widths, message):
    assert construction_error(lambda: DelayCore(**widths), ValueError) == message


def test_trigger_refuses_width_bits(construction_error):
    assert construction_error(lambda: LaserTrigger(width_bits=0), ValueError) == \
        "Pulse width bits must be a positive integer, not 0"


def test_interval_mode_intervals_are_period_plus_delay():
    # Equation 3, worked out from the delays alone.
    settings = Settings(mode=DelayMode.MSEQ, length=5, seed=1, period=40, pulse_width=2)
    expected = check_against_model(settings, 4000)
    delays = np.array([d for _, d, _, _ in expected])
    fires = np.array([f for f, *_ in expected])
    assert np.array_equal(np.diff(fires), 40 + delays[1:])


def test_grid_mode_is_on_the_nominal_grid():
    settings = Settings(mode=DelayMode.MSEQ, length=4, seed=3, period=30, grid=True,
                        pulse_width=3)
    expected = check_against_model(settings, 3000)
    fires = np.array([f for f, *_ in expected])
    delays = np.array([d for _, d, _, _ in expected])
    assert np.array_equal(fires - delays, fires[0] - delays[0] + 30 * np.arange(len(fires)))


def test_reconfiguration_in_the_middle_of_a_run():
    rng = random.Random(11)
    settings = Settings(mode=DelayMode.MSEQ, length=4, seed=1, period=25, pulse_width=2)
    updates, cycle = [], 30
    for _ in range(30):
        cycle += rng.randrange(1, 90)
        grid = rng.random() < 0.3
        updates.append((cycle, Settings(
            mode=rng.choice(SEEDED_MODES), length=rng.choice([3, 4]),
            mask_width=rng.choice([1, 2, 3]), seed=rng.randrange(1, 8),
            period=rng.randrange(20, 40), grid=grid, pulse_width=rng.randrange(1, 5)).check()))
    expected = check_against_model(settings, cycle + 200, updates=updates)
    assert len(expected) > 40
    # The laser always goes low between pulses.
    pulses, laser, _ = run_core(settings, cycle + 200, updates=updates)
    trace = laser_pulses(laser)
    assert all(rise + width < next_rise for (rise, width), (next_rise, _) in zip(trace, trace[1:]))


def test_update_in_a_take_cycle_applies_to_the_next_frame():
    # Frame boundaries of the first settings are known: update exactly on one, and one cycle
    # before it, and check the model's rule (frames whose take comes after the update).
    settings = Settings(mode=DelayMode.OFF, period=10, pulse_width=1)
    other = Settings(mode=DelayMode.MSEQ, length=3, seed=1, period=13, pulse_width=2)
    take = 1 + 1 + 3 * 10  # enable at 1, b[0] = 2, b[3] = 32
    for update in (take - 1, take, take + 1):
        expected = check_against_model(settings, 200, updates=[(update, other)])
        fires = [f for f, *_ in expected]
        first_new = take + 1 if update < take else take + 10 + 1
        assert first_new in fires
        assert expected[fires.index(first_new)][1:3] == (0, 2)  # first mseq delay, new width


def test_stop_and_restart():
    settings = Settings(mode=DelayMode.MSEQ, length=5, seed=7, period=20, pulse_width=4)
    pulses, laser, _ = run_core(settings, 600, enable=3, disable=300)
    expected = simulate(settings, 599, enable=3, disable=300)
    assert [(f, d, i) for f, d, _, i in pulses] == [(f, d, i) for f, d, _, i in expected]
    assert max(f for f, *_ in pulses) < 300
    assert not laser[300 + 4:].any()


_SHORT_STOP_SETTINGS = [
    Settings(mode=DelayMode.MASKED, mask_width=3, seed=5, period=9, pulse_width=2),
    Settings(mode=DelayMode.MSEQ, length=3, seed=2, period=11, grid=True, pulse_width=1),
    Settings(mode=DelayMode.OFF, period=2, pulse_width=1),
    Settings(mode=DelayMode.OFF, period=3, grid=True, pulse_width=2),
    Settings(mode=DelayMode.OFF, period=2, grid=True, pulse_width=1),
]


@pytest.mark.parametrize("before", range(len(_SHORT_STOP_SETTINGS)))
@pytest.mark.parametrize("after", range(len(_SHORT_STOP_SETTINGS)))
@pytest.mark.parametrize("gap", [1, 2])
def test_short_stops(before, after, gap):
    # `enable` low for one or two cycles, at every point of a few frames, with other settings
    # presented during the stop: the restarted run is a new run with them (pulse index and
    # delay sequence from the start), as in the model.
    settings, restarted = _SHORT_STOP_SETTINGS[before], _SHORT_STOP_SETTINGS[after]
    cycles = 100
    for stop in range(30, 30 + 2 * settings.period):
        restart = stop + gap
        pulses, laser, _ = run_core(settings, cycles, present=[(stop, restarted)],
                                enable=lambda cycle, stop=stop, restart=restart:
                                    1 <= cycle < stop or cycle >= restart)
        before = simulate(settings, cycles - 1, enable=1, disable=stop)
        expected = before + simulate(restarted, cycles - 1,
                                     enable=start_cycle(restart, before))
        assert [(f, d, i) for f, d, _, i in pulses] == \
            [(f, d, i) for f, d, _, i in expected], (stop, gap)
        # (and the laser never merges two pulses: each is exactly as wide as asked)
        np.testing.assert_array_equal(np.asarray(laser, dtype=bool),
                                      laser_waveform(expected, len(laser)), str((stop, gap)))


def test_laser_trigger_width_and_tdc_start():
    dut = LaserTrigger()
    trace = []

    async def testbench(ctx):
        schedule = {2: 1, 10: 5, 20: 0, 30: 3}
        for cycle in range(40):
            ctx.set(dut.fire, cycle in schedule)
            ctx.set(dut.width, schedule.get(cycle, 9))
            trace.append((ctx.get(dut.laser), ctx.get(dut.tdc_start)))
            await ctx.tick()

    run_simulation(dut, testbench, clock_hz=100e6)
    laser = np.array([level for level, _ in trace])
    starts = [c for c, (_, s) in enumerate(trace) if s]
    assert laser_pulses(laser) == [(3, 1), (11, 5), (21, 1), (31, 3)]  # width 0 acts as 1
    assert starts == [3, 11, 21, 31]


def test_fire_cycles_vectorised_matches_simulate():
    settings = Settings(mode=DelayMode.MASKED, mask_width=5, seed=77, period=50, pulse_width=1)
    delays = settings.delays(500)
    fires = fire_cycles(delays, 50, start=2)
    expected = simulate(settings, int(fires[-1]), enable=1)
    assert fires.tolist() == [f for f, *_ in expected]


@pytest.mark.parametrize("args, kwargs, message", [
    ((1, 1), {}, r"^Period must be from 2 to 4294967295 clock cycles, not 1$"),
    ((80, 0), {}, r"^Pulse width must be from 1 to 65535 clock cycles, not 0$"),
    ((80, 80), {}, r"^Pulse width \(80 cycles\) must be shorter than the period \(80 cycles\)$"),
    ((80, 18), dict(grid=True, max_delay=62),
     r"^Grid mode needs the largest delay plus the pulse width \(62 \+ 18 cycles\) to be shorter "
     r"than the period \(80 cycles\); use interval mode, a longer period or a shorter delay$"),
])
def test_bad_schedule(args, kwargs, message):
    with pytest.raises(ValueError, match=message):
        check_schedule(*args, **kwargs)


def test_grid_refuses_long_delays_through_settings():
    with pytest.raises(ValueError, match=r"^Grid mode needs"):
        Settings(mode=DelayMode.MSEQ, length=7, period=80, grid=True).check()
    Settings(mode=DelayMode.MSEQ, length=6, period=80, grid=True, pulse_width=17).check()


@pytest.mark.parametrize("clock, prf, period", [(80e6, 1e6, 80), (79.5e6, 1e6, 80),
                                                (12e6, 1e6, 12), (80e6, 3e5, 267)])
def test_period_cycles(clock, prf, period):
    assert period_cycles(clock, prf) == period


def test_period_cycles_errors():
    with pytest.raises(ValueError, match=r"^Pulse repetition frequency must be positive, not 0$"):
        period_cycles(80e6, 0)
    with pytest.raises(ValueError, match=r"the period must be at least 2 cycles$"):
        period_cycles(80e6, 60e6)
