"""The table of delay modes (hdl/delay/modes.py) against the sequences the model makes, and the
register file's consistency check (generated from the table) against the table's largest
delays."""

from fractions import Fraction

import numpy as np
import pytest

from fliss.hdl.delay.modes import MODES, DelayMode, delay_problems, label, mode_row
from fliss.hdl.regfile import RegisterFile
from fliss.hdl.registers import BY_NAME, defaults, problems
from fliss.sim.models import delay as model
from simulation import simulate


#: A few values of each size setting (None: a mode without one).
SIZES = {None: [None], "length": [2, 3, 5, 8, 11], "mask_width": [1, 3, 6, 10]}

#: Every mode of the table, with a few values of its size setting.
CASES = [(mode, n) for mode, row in MODES.items() for n in SIZES[row.size]]

#: Delays generated where the period is too long to generate whole.
LONG_RUN = 1 << 18


def _settings(mode, n):
    row = MODES[mode]
    settings = {"length": None, "mask_width": None}
    if row.size is not None:
        settings[row.size] = n
    keying = dict(key=0x0123456789ABCDEF0123, iv=0x42) if row.keyed else {}
    return settings, keying


def test_every_mode_has_a_row():
    assert list(MODES) == list(DelayMode)
    needs = {DelayMode.OFF: (), DelayMode.MSEQ: ("length", "seed"),
             DelayMode.MASKED: ("mask_width", "seed"), DelayMode.KEYED: ("mask_width", "key", "iv")}
    assert {mode: MODES[mode].needs for mode in needs} == needs
    assert [MODES[mode].name for mode in needs] == ["off", "mseq", "masked", "keyed"]


@pytest.mark.parametrize("mode, n", CASES)
def test_max_delay_is_reached_and_never_exceeded(mode, n):
    settings, keying = _settings(mode, n)
    row = MODES[mode]
    period = row.sequence_period(**settings)
    count = period if period is not None and period <= LONG_RUN else LONG_RUN
    delays = model.delays(mode, count, seed=3, **settings, **keying)
    # worked out here: R = state - 1 of an n-bit register (mseq), n bits (masked, keyed), 0 (off)
    expected = {DelayMode.OFF: 0, DelayMode.MSEQ: (1 << (n or 0)) - 2}.get(mode,
                                                                          (1 << (n or 0)) - 1)
    assert row.max_delay(**settings) == expected
    assert delays.max() == expected and delays.min() == 0


@pytest.mark.parametrize("mode, n", CASES)
def test_sequence_period(mode, n):
    settings, keying = _settings(mode, n)
    period = MODES[mode].sequence_period(**settings)
    if mode == DelayMode.KEYED:
        assert period is None
        return
    if period > LONG_RUN:
        if mode != DelayMode.MASKED:
            pytest.skip(f"a period of {period} pulses, too long to generate")
        # (masked: 2**32 - 1, too long to generate) no repeat within the run
        assert period == (1 << 32) - 1
        delays = model.delays(mode, LONG_RUN, seed=3, **settings)
        states = model.lfsr.states(32, 3, LONG_RUN, steps=16)
        assert len(np.unique(states)) == LONG_RUN
        assert np.array_equal(delays, states.astype(np.int64) & ((1 << n) - 1))
        return
    delays = model.delays(mode, 2 * period, seed=3, **settings)
    assert np.array_equal(delays[:period], delays[period:])
    # and not a shorter one: no proper divisor of the period repeats the sequence
    for shorter in range(1, period):
        if period % shorter == 0:
            assert not np.array_equal(delays[:period - shorter], delays[shorter:period])


@pytest.mark.parametrize("mode, n", CASES)
def test_mean_delay(mode, n):
    settings, keying = _settings(mode, n)
    row = MODES[mode]
    mean = row.mean_delay(**settings)
    assert isinstance(mean, Fraction)
    period = row.sequence_period(**settings)
    if period is not None and period <= LONG_RUN:
        # exactly, over one whole period
        delays = model.delays(mode, period, seed=3, **settings, **keying)
        assert Fraction(int(delays.sum()), period) == mean
        return
    # masked (a period of 2**32 - 1) and keyed (none known): the mean of a long run, within
    # 5 standard errors of uniform delays of 0 … 2**n - 1
    delays = model.delays(mode, LONG_RUN, seed=3, **settings, **keying)
    sigma = (1 << n) / np.sqrt(12) / np.sqrt(LONG_RUN)
    assert abs(delays.mean() - float(mean)) < 5 * sigma
    assert abs(float(mean) - ((1 << n) - 1) / 2) < 1e-6


def test_the_model_reads_the_table():
    for mode, n in CASES:
        settings, _ = _settings(mode, n)
        row = MODES[mode]
        assert model.max_delay(mode, **settings) == row.max_delay(**settings)
        assert model.mean_delay(mode, **settings) == row.mean_delay(**settings)
        assert model.sequence_period(mode, **settings) == row.sequence_period(**settings)


@pytest.mark.parametrize("mode, settings, text", [
    (DelayMode.OFF, dict(length=6, mask_width=4), "off"),
    (DelayMode.MSEQ, dict(length=6, mask_width=4), "mseq L=6"),
    (DelayMode.MASKED, dict(length=6, mask_width=4), "masked Wm=4"),
    (DelayMode.KEYED, dict(length=6, mask_width=4), "keyed Wm=4"),
    (3, dict(length=6, mask_width=5), "keyed Wm=5"),
    (7, dict(length=6, mask_width=5), "?"),
    (None, {}, "?"),
])
def test_labels(mode, settings, text):
    assert label(mode, **settings) == text
    assert (mode_row(mode) is None) == (text == "?")


def _grid_cases():
    # For each mode and a few sizes: the grid condition just met, and just missed
    cases = []
    for row in MODES.values():
        for n in {"length": [2, 5, 9], "mask_width": [1, 4, 7]}.get(row.size, [None]):
            values = dict(delay_mode=row.mode.value, length=n if row.size == "length" else 6,
                          mask_width=n if row.size == "mask_width" else 6, seed=1, grid=1,
                          pulse_width=3)
            largest = row.max_delay(length=values["length"], mask_width=values["mask_width"])
            for period, consistent in ((largest + 4, True), (largest + 3, False)):
                cases.append((dict(values, period=period), consistent))
    return cases


def test_register_file_grid_check_uses_the_table():
    # The gateware's consistency check, generated from the table, against the table's largest
    # delay: a grid needs it plus the pulse width to be shorter than the period.
    cases = _grid_cases()
    dut = RegisterFile()
    order = ["delay_mode", "length", "mask_width", "seed", "period", "grid", "pulse_width"]
    assert [BY_NAME[name].address for name in order] == list(range(1, 8))
    results = []

    async def testbench(ctx):
        for values, _ in cases:
            ctx.set(dut.begin, 1)
            await ctx.tick()
            ctx.set(dut.begin, 0)
            ctx.set(dut.start, 1)
            ctx.set(dut.start_address, 1)
            await ctx.tick()
            ctx.set(dut.start, 0)
            for name in order:
                ctx.set(dut.value, values[name])
                await ctx.tick()
                ctx.set(dut.check, 1)
                await ctx.tick()
                ctx.set(dut.check, 0)
            await ctx.tick().repeat(5)
            results.append((bool(ctx.get(dut.consistent)), bool(ctx.get(dut.error))))

    simulate(dut, testbench)
    expected = [consistent for _, consistent in cases]
    assert [consistent for consistent, _ in results] == expected
    assert not any(error for _, error in results)
    # Independently, the Python rules say the same
    assert [problems({**defaults(80_000_000), **values}) == [] for values, _ in cases] == expected
    assert expected.count(False) == len(cases) // 2 >= 9


#: Delay settings every check passes: mseq, length 5, in interval mode.
GOOD = dict(mode=DelayMode.MSEQ, length=5, mask_width=6, seed=17, period=40, grid=0,
            pulse_width=2)


@pytest.mark.parametrize("change, messages", [
    ({}, []),
    ({"mode": 3, "mask_width": 16, "seed": 1 << 31}, []),
    ({"grid": 1, "period": 33}, []),    # the largest delay 30 plus the pulse 2 is below 33
    ({"grid": 1, "period": 32},
     ["grid mode needs the largest delay plus pulse_width to be shorter than period"]),
    ({"pulse_width": 40}, ["pulse_width (40 cycles) must be shorter than period (40 cycles)"]),
    ({"seed": 32}, ["seed must be below 2**length = 32 for the mseq source"]),
    ({"mode": 4}, ["mode (4) is no delay mode"]),
    ({"length": 33, "period": 1},
     ["length must be an integer from 2 to 32, not 33",
      "period must be an integer from 2 to 4294967295, not 1"]),
    ({"seed": 0}, ["seed must be an integer from 1 to 4294967295, not 0"]),
])
def test_delay_problems(change, messages):
    # A delay core's settings checked without the register file (a design of one's own)
    assert delay_problems({**GOOD, **change}) == messages


def test_delay_problems_names_and_missing_fields():
    assert delay_problems({**GOOD, "pulse_width": 50}, names={"pulse_width": "width"}) == \
        ["width (50 cycles) must be shorter than period (40 cycles)"]
    settings = dict(GOOD)
    del settings["grid"], settings["seed"]
    assert delay_problems(settings) == ["missing delay settings: seed, grid"]
