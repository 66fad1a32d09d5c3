"""GF(2) linear algebra and Berlekamp-Massey, against answers worked out independently."""

import numpy as np
import pytest

from fliss.hdl.delay.lfsr import POLYNOMIALS
from fliss.sim.studies import gf2


def _galois_bits(poly, length, seed, count):
    # Bit 0 of a right-shifting Galois register, written here from its definition.
    state, out = seed, []
    for _ in range(count):
        out.append(state & 1)
        state = (state >> 1) ^ ((poly >> 1) if state & 1 else 0)
    return out


@pytest.mark.parametrize("length", [2, 3, 5, 8, 13, 16, 24, 32])
def test_berlekamp_massey_finds_the_table_polynomial(length):
    # The register multiplies its state by 1/x modulo P, so each output bit stream obeys
    # s[n] = sum(p_j s[n-j]): the connection polynomial is P itself, and an m-sequence of a
    # primitive P of degree L has linear complexity exactly L (2L bits determine it).
    poly = POLYNOMIALS[length]
    bits = _galois_bits(poly, length, 1, 2 * length + 10)
    for n in range(length, len(bits)):
        assert bits[n] == sum((poly >> j & 1) * bits[n - j] for j in range(1, length + 1)) % 2
    assert gf2.berlekamp_massey(bits) == (length, poly)
    assert gf2.berlekamp_massey(bits[:2 * length]) == (length, poly)


@pytest.mark.parametrize("bits, expected", [
    ([0] * 10, (0, 1)),
    ([1] * 10, (1, 0b11)),                  # s[n] = s[n-1]
    ([1, 0] * 6, (2, 0b101)),               # s[n] = s[n-2]
    ([0, 0, 0, 0, 1], (5, None)),           # 0...01 of length n has complexity n
    ([1], (1, None)),
])
def test_berlekamp_massey_small_cases(bits, expected):
    length, connection = gf2.berlekamp_massey(bits)
    assert length == expected[0]
    if expected[1] is not None:
        assert connection == expected[1]


def test_berlekamp_massey_on_random_bits_grows_as_half_the_length():
    # For random bits the linear complexity stays within a few bits of n / 2.
    rng = np.random.default_rng(5)
    bits = rng.integers(0, 2, 400)
    length, _ = gf2.berlekamp_massey(bits)
    assert abs(length - 200) <= 6
    with pytest.raises(ValueError, match="Bits must be 0 or 1"):
        gf2.berlekamp_massey([0, 2])


def _random_invertible(size, rng):
    # The identity mixed by random row additions: invertible by construction.
    rows = [1 << i for i in range(size)]
    for _ in range(20 * size):
        a, b = rng.choice(size, 2, replace=False)
        rows[a] ^= rows[b]
    return rows


def _times(rows, x):
    return sum(((bin(row & x).count("1") & 1) << i) for i, row in enumerate(rows))


@pytest.mark.parametrize("seed", range(6))
def test_solve_full_rank_systems(seed):
    rng = np.random.default_rng(seed)
    rows = _random_invertible(32, rng)
    extra = [int(v) for v in rng.integers(0, 1 << 32, 8)]
    x = int(rng.integers(1, 1 << 32))
    system = rows + extra
    assert gf2.rank(system, 32) == 32
    assert gf2.solve(system, _times(system, x), 32) == x
    inverse = gf2.left_inverse(system, 32)
    assert gf2.apply(inverse, _times(system, x)) == x


def test_solve_inconsistent_and_rank_deficient():
    rows = [0b011, 0b110, 0b101]                # row 3 = row 1 + row 2: rank 2
    assert gf2.rank(rows, 3) == 2
    assert gf2.solve(rows, 0b111, 3) is None    # 1, 1, 1 breaks row 3 = row 1 + row 2
    solution = gf2.solve(rows, 0b000, 3)
    assert _times(rows, solution) == 0
    with pytest.raises(ValueError, match="rank 2, not 3"):
        gf2.left_inverse(rows, 3)
    assert gf2.parity(0b1011) == 1 and gf2.parity(0) == 0
