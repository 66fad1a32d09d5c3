"""Delay sources: statistics of the model, effective PRF, and the gateware against the model."""

from fractions import Fraction

import numpy as np
import pytest

from fliss.hdl.delay.source import DelayMode, DelaySource
from fliss.sim.models import delay as model
from fliss.sim.models.scheduler import effective_prf, fire_cycles, measured_prf
from simulation import simulate


#: Paper, Table 2: effective PRF at 80 MHz, 1 MHz nominal, complete m-sequences (Hz, as printed).
TABLE_2 = {3: (963.9e3, 100), 4: (919.5e3, 100), 5: (842.1e3, 100), 6: (720.7e3, 100),
           8: (386.5e3, 100), 16: (2.4e3, 100), 32: (0.04, 0.01)}


@pytest.mark.parametrize("length", [2, 3, 4, 5, 6, 8, 10, 12])
def test_mseq_covers_every_delay_once_per_period(length):
    period = (1 << length) - 1
    delays = model.delays("mseq", 2 * period, length=length, seed=5 % period or 1)
    assert sorted(delays[:period]) == list(range(period))   # R = 0 … 2**L - 2
    assert np.array_equal(delays[:period], delays[period:])


@pytest.mark.parametrize("length", [3, 4, 5, 6, 8, 16, 32])
def test_table_2_closed_form(length):
    # Equation 4 with E(R) = (2**L - 2) / 2, worked out here, and to the digits of the paper.
    mean = Fraction((1 << length) - 2, 2)
    assert model.mean_delay("mseq", length=length) == mean
    prf = effective_prf(80_000_000, 80, mean)
    assert prf == Fraction(80_000_000) / (80 + mean)
    paper, resolution = TABLE_2[length]
    assert abs(float(prf) - paper) <= resolution / 2


@pytest.mark.parametrize("length", [3, 4, 5, 6, 8, 12, 16])
def test_effective_prf_measured_over_whole_sequences(length):
    period = (1 << length) - 1
    delays = model.delays("mseq", period + 1, length=length, seed=1)
    measured = measured_prf(80_000_000, fire_cycles(delays, 80))
    closed = effective_prf(80_000_000, 80, model.mean_delay("mseq", length=length))
    assert measured == closed


@pytest.mark.parametrize("mask_width", [1, 2, 6, 8, 12])
def test_masked_mean_delay(mask_width):
    # Closed form over the whole period, against the mean of a long run.
    delays = model.delays("masked", 200_000, mask_width=mask_width, seed=12345)
    expected = float(model.mean_delay("masked", mask_width=mask_width))
    sigma = ((1 << mask_width) / np.sqrt(12)) / np.sqrt(len(delays))
    assert abs(delays.mean() - expected) < 5 * sigma
    assert abs(expected - ((1 << mask_width) - 1) / 2) < 1e-6


@pytest.fixture(scope="module")
def masked_million():
    return model.delays("masked", 1_000_000, mask_width=16, seed=0xC0FFEE)


@pytest.mark.parametrize("mask_width", range(1, 17))
def test_masked_uniform_and_uncorrelated(masked_million, mask_width):
    delays = masked_million & ((1 << mask_width) - 1)
    bins = 1 << mask_width
    counts = np.bincount(delays, minlength=bins)
    expected = len(delays) / bins
    chi2 = float(((counts - expected) ** 2 / expected).sum())
    dof = bins - 1
    # Wilson-Hilferty: chi2 / dof is close to normal; reject beyond 4 sigma either way.
    z = ((chi2 / dof) ** (1 / 3) - (1 - 2 / (9 * dof))) / np.sqrt(2 / (9 * dof))
    assert abs(z) < 4, (chi2, dof, z)
    lag1 = np.corrcoef(delays[:-1], delays[1:])[0, 1]
    assert abs(lag1) < 0.01, lag1


def test_masked_delays_are_not_shifted_copies():
    # With one register step per pulse, delay[k+1] would be delay[k] >> 1 plus one new bit most
    # of the time; the source takes enough steps that this happens by chance only (1 in 2**(W-1)).
    delays = model.delays("masked", 100_000, mask_width=6, seed=99)
    shifted = np.mean((delays[1:] & 0x1f) == (delays[:-1] >> 1))
    assert abs(shifted - 1 / 32) < 0.005


@pytest.mark.parametrize("kwargs, message", [
    (dict(mode="mseq", length=1), r"^LFSR length must be an integer from 2 to 32, not 1$"),
    (dict(mode="mseq"), r"^The mseq delay source needs a register length L$"),
    (dict(mode="masked", mask_width=17), r"^Mask width must be an integer from 1 to 16, not 17$"),
    (dict(mode="mseq", length=4, seed=0),
     r"^Seed must be an integer from 1 to 15 \(a non-zero 4-bit register state\), not 0$"),
    (dict(mode="mseq", length=4, seed=16),
     r"^Seed must be an integer from 1 to 15 \(a non-zero 4-bit register state\), not 16$"),
    (dict(mode="random"), r"^Delay mode must be one of off, mseq, masked, keyed, not 'random'$"),
])
def test_bad_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        model.check_settings(**kwargs)


def test_gateware_against_model():
    # Each mode and several settings, with a PRBS on `ready` and reloads in between.
    dut = DelaySource()
    cases = [(DelayMode.MSEQ, dict(length=length, seed=seed))
             for length, seed in [(3, 5), (4, 1), (6, 33), (8, 200), (16, 0xBEEF), (32, 7)]] + \
            [(DelayMode.MASKED, dict(mask_width=width, seed=0x12345678 + width))
             for width in (1, 3, 6, 16)] + \
            [(DelayMode.OFF, dict(seed=1))]
    errors = []

    async def testbench(ctx):
        rng = np.random.default_rng(7)
        for mode, settings in cases:
            ctx.set(dut.settings.mode, mode)
            ctx.set(dut.settings.length, settings.get("length", 2))
            ctx.set(dut.settings.mask_width, settings.get("mask_width", 1))
            ctx.set(dut.settings.seed, settings["seed"])
            ctx.set(dut.load, 1)
            await ctx.tick()
            ctx.set(dut.load, 0)
            expected = model.delays(mode, 500, **settings).tolist()
            index = 0
            while index < 500:
                ready = bool(rng.integers(0, 3))
                ctx.set(dut.delays.ready, ready)
                if not ctx.get(dut.delays.valid) or ctx.get(dut.delays.payload.value) != expected[index]:
                    errors.append((mode, settings, index))
                await ctx.tick()
                index += ready
            ctx.set(dut.delays.ready, 0)

    simulate(dut, testbench, clock_hz=100e6)
    assert errors == []


def test_scheduler_hints_against_model():
    # The hints the scheduler reads at a transfer: `zero` (R == 0, low in the cycle after a load)
    # and `zero_late` (R == 0 of a transfer made in the cycle after a load, a cycle later), with
    # transfers at least two cycles apart as the scheduler makes them, reloads in between, and
    # seeds that load as 1 (all-zero low bits).
    from fliss.sim.models import lfsr
    dut = DelaySource()
    cases = [(DelayMode.MSEQ, 5, 1, 0x20), (DelayMode.MSEQ, 4, 1, 9), (DelayMode.MSEQ, 3, 1, 1),
             (DelayMode.MASKED, 2, 3, 0), (DelayMode.MASKED, 2, 2, 0x1234),
             (DelayMode.OFF, 2, 1, 5)]
    errors, checked = [], [0, 0]

    def expected(mode, length, width, seed, count):
        if mode == DelayMode.MSEQ:
            return (lfsr.states(length, seed, count).astype(np.int64) - 1).tolist()
        if mode == DelayMode.MASKED:
            states = lfsr.states(32, seed, count, steps=16)
            return (states & np.uint64((1 << width) - 1)).astype(np.int64).tolist()
        return [0] * count

    async def testbench(ctx):
        rng = np.random.default_rng(3)
        for mode, length, width, seed in cases * 3:
            ctx.set(dut.settings.mode, mode)
            ctx.set(dut.settings.length, length)
            ctx.set(dut.settings.mask_width, width)
            ctx.set(dut.settings.seed, seed)
            ctx.set(dut.load, 1)
            await ctx.tick()
            ctx.set(dut.load, 0)
            delays = expected(mode, length, width, seed, 60)
            index, fresh, late = 0, True, None
            while index < 60:
                ready = bool(rng.integers(0, 2)) and late is None or fresh and index == 0 and \
                    bool(rng.integers(0, 2))
                if ctx.get(dut.delays.payload.value) != delays[index]:
                    errors.append(("payload", mode, seed, index))
                if late is not None:
                    checked[1] += 1
                    if ctx.get(dut.delays.payload.zero_late) != (late == 0):
                        errors.append(("zero_late", mode, seed, index))
                    late = None
                elif ready and not fresh:
                    checked[0] += 1
                    if ctx.get(dut.delays.payload.zero) != (delays[index] == 0):
                        errors.append(("zero", mode, seed, index))
                if ready:
                    if fresh:
                        late = delays[index]
                    elif ctx.get(dut.delays.payload.zero_late):
                        errors.append(("zero_late high", mode, seed, index))
                ctx.set(dut.delays.ready, ready)
                await ctx.tick()
                ctx.set(dut.delays.ready, 0)
                if ready:
                    index += 1
                    # transfers by the scheduler are at least two cycles apart
                    if late is None:
                        await ctx.tick()
                fresh = False

    simulate(dut, testbench, clock_hz=100e6)
    assert errors == []
    assert checked[0] > 200 and checked[1] > 3
