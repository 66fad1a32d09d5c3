"""The polynomial table, the LFSR model, and the LFSR gateware against the model."""

import numpy as np
import pytest

from fliss.hdl.delay.lfsr import Lfsr, POLYNOMIALS
from fliss.sim.models import lfsr as model

from simulation import simulate


# Polynomial arithmetic over GF(2), written here independently of the code under test.

def _prime_factors(n):
    factors, d = set(), 2
    while d * d <= n:
        while n % d == 0:
            factors.add(d)
            n //= d
        d += 1
    if n > 1:
        factors.add(n)
    return factors


def _mulmod(a, b, poly, degree):
    result = 0
    while b:
        if b & 1:
            result ^= a
        b >>= 1
        a <<= 1
        if a >> degree & 1:
            a ^= poly
    return result


def _x_power(exponent, poly, degree):
    result, base = 1, 2
    while exponent:
        if exponent & 1:
            result = _mulmod(result, base, poly, degree)
        base = _mulmod(base, base, poly, degree)
        exponent >>= 1
    return result


def test_table_covers_every_length():
    assert sorted(POLYNOMIALS) == list(range(2, 33))
    for length, poly in POLYNOMIALS.items():
        assert poly.bit_length() == length + 1 and poly & 1, length


@pytest.mark.parametrize("length", range(2, 33))
def test_polynomial_is_primitive(length):
    # x has multiplicative order exactly 2**L - 1 modulo P: then P is irreducible and primitive.
    poly, order = POLYNOMIALS[length], (1 << length) - 1
    assert _x_power(order, poly, length) == 1
    for factor in _prime_factors(order):
        assert _x_power(order // factor, poly, length) != 1, factor


@pytest.mark.parametrize("length", range(2, 21))
def test_period_exhaustive(length):
    # Every non-zero state once per period of 2**L - 1 steps, then the sequence repeats.
    period = (1 << length) - 1
    states = model.states(length, 1, period + 1)
    assert states[period] == states[0]
    assert len(np.unique(states[:period])) == period
    assert states[:period].min() == 1 and states[:period].max() == period


def _reference_step(state, length):
    # Multiplication by x**-1 modulo P, done on the polynomial: independent of model.step.
    poly = POLYNOMIALS[length]
    if state & 1:
        state ^= poly
    return state >> 1


@pytest.mark.parametrize("length", [2, 3, 7, 8, 16, 31, 32])
@pytest.mark.parametrize("steps", [1, 16])
def test_vectorised_states_match_stepping(length, steps):
    seed = 0x9E3779B9 & ((1 << length) - 1) or 1
    states = model.states(length, seed, 10_000, steps=steps, block=257)
    state = seed
    for index in range(10_000):
        assert states[index] == state, index
        for _ in range(steps):
            state = _reference_step(state, length)


def test_load_never_zero():
    assert model.load(0x100, 8) == 1
    assert model.load(0x1ff, 8) == 0xff


def test_model_rejects_bad_length():
    with pytest.raises(ValueError, match=r"^LFSR length must be an integer from 2 to 32, not 33$"):
        model.states(33, 1, 4)


def test_gateware_rejects_bad_parameters(construction_error):
    assert construction_error(lambda: Lfsr(length=1), TypeError) == \
        "Length must be None or an integer from 2 to 32, not 1"
    assert construction_error(lambda: Lfsr(length=8, steps=0), TypeError) == \
        "Steps must be a positive integer, not 0"
    assert construction_error(lambda: Lfsr(steps=4)) == \
        "Only a fixed-length register can take 4 steps per advance"


def test_gateware_runtime_length():
    # Every length, loaded with a seed whose low bits may be zero, stepped with gaps, then
    # reloaded with another length: the states are the model's.
    dut = Lfsr()
    mismatches = []

    async def testbench(ctx):
        rng = np.random.default_rng(1)
        for length in range(2, 33):
            seed = int(rng.integers(0, 1 << 32)) if length != 5 else 0x20  # low 5 bits zero
            ctx.set(dut.length, length)
            ctx.set(dut.seed, seed)
            ctx.set(dut.load, 1)
            await ctx.tick()
            ctx.set(dut.load, 0)
            ctx.set(dut.length, 2)  # sampled on load only
            expected = model.states(length, seed, 300)
            index = 0
            while index < 300:
                if ctx.get(dut.state) != expected[index]:
                    mismatches.append((length, index))
                advance = bool(rng.integers(0, 4))
                ctx.set(dut.advance, advance)
                await ctx.tick()
                index += advance
            ctx.set(dut.advance, 0)

    simulate(dut, testbench)
    assert mismatches == []


def test_gateware_fixed_length_multistep():
    dut = Lfsr(length=32, steps=16)
    expected = model.states(32, 0xDEADBEEF, 2000, steps=16)
    got = []

    async def testbench(ctx):
        ctx.set(dut.seed, 0xDEADBEEF)
        ctx.set(dut.load, 1)
        await ctx.tick()
        ctx.set(dut.load, 0)
        ctx.set(dut.advance, 1)
        for _ in range(2000):
            got.append(ctx.get(dut.state))
            await ctx.tick()

    simulate(dut, testbench)
    assert got == expected.tolist()
