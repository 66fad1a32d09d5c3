"""The attacker: lock counts against theory, honest failure on unpredictable sources,
predictions equal to the victim's delays, jitter, missed pulses, grid mode, bad settings."""

import math

import numpy as np
import pytest

from fliss.sim.studies.attacker import Attacker, Observer
from fliss.sim.studies.generators import KnownTaps
from fliss.sim.models import delay as delay_model
from fliss.sim.studies import gf2
from fliss.sim.studies.attack_scene import Victim


@pytest.fixture(scope="module")
def attacker():
    return Attacker(80)


@pytest.fixture(scope="module")
def blind():
    return Attacker(80, known_taps=False)


def _verify(width):
    # The lock rule: at least 4 checked pulses and at least 48 checked bits.
    return max(4, math.ceil(48 / width))


def _attack(attacker, victim, count, observer=None):
    observer = Observer(seed=3) if observer is None else observer
    starts = victim.start_cycles(count, start=50)
    times, seen = observer.observe(starts)
    return attacker.attack(times), seen, victim.delays(count)


def _check_predictions(result, seen, delays, count=2000):
    """Every lock's predictions equal the victim's delays from its base pulse on."""
    for lock in result.locks:
        first = seen[lock.base]
        actual = delays[first:first + count]
        assert np.array_equal(lock.predicted[:len(actual)], actual[:len(lock.predicted)])


@pytest.mark.parametrize("length, seed", [(8, 0xB5), (12, 0xACE), (16, 0xACE1), (24, 0xC0FFEE)])
def test_mseq_known_taps_lock(attacker, length, seed):
    # The delay is the whole register minus one: one pulse gives the state. Theory: the first
    # pulse (no interval before it, delay unreadable) + 1 pulse + the checked pulses.
    victim = Victim("mseq", length=length, seed=seed)
    result, seen, delays = _attack(attacker, victim, 400)
    assert max(int(d).bit_length() for d in delays[1:2 + _verify(length)]) == length
    assert result.locked_after == 1 + 1 + _verify(length)
    assert result.model == f"mseq L={length}, known taps"
    assert len(result.locks) == 1
    _check_predictions(result, seen, delays)


def _rank(matrix):
    # Gaussian elimination over GF(2) on a numpy 0/1 matrix, written here for the tests.
    matrix, rank = matrix.copy() % 2, 0
    for column in range(matrix.shape[1]):
        rows = np.flatnonzero(matrix[rank:, column]) + rank
        if len(rows) == 0:
            continue
        matrix[[rank, rows[0]]] = matrix[[rows[0], rank]]
        others = np.flatnonzero(matrix[:, column])
        matrix[others[others != rank]] ^= matrix[rank]
        rank += 1
    return rank


def _masked_solve_pulses(width):
    """Fewest pulses whose delays determine the 32-bit register: the rank of the map from seed
    to delays, column by column from the delays of single-bit seeds (the map is linear)."""
    for pulses in range(-(-32 // width), 64):
        columns = [[(int(d) >> j) & 1
                    for d in delay_model.delays("masked", pulses, mask_width=width, seed=1 << bit)
                    for j in range(width)]
                   for bit in range(32)]
        if _rank(np.array(columns, dtype=np.uint8).T) == 32:
            return pulses
    raise AssertionError("never determined")


@pytest.mark.parametrize("width, expected", [(1, 32), (2, 16), (4, 9), (6, 6), (8, 5), (16, 2)])
def test_masked_rank(width, expected):
    # ceil(32 / Wm) pulses carry 32 bits, but for some Wm they are linearly dependent.
    assert _masked_solve_pulses(width) == expected
    assert KnownTaps("masked", width).solve_pulses == expected


@pytest.mark.parametrize("width", [2, 4, 6, 8, 12, 16])
def test_masked_known_taps_lock(attacker, width):
    # Wm bits a pulse: the state needs about ceil(32 / Wm) pulses (see test_masked_rank).
    victim = Victim("masked", mask_width=width, seed=0x12345678)
    result, seen, delays = _attack(attacker, victim, 600)
    need = _masked_solve_pulses(width)
    assert need - -(-32 // width) in (0, 1)
    assert max(int(d).bit_length() for d in delays[1:1 + need + _verify(width)]) == width
    assert result.locked_after == 1 + need + _verify(width)
    assert result.model == f"masked Wm={width}, known taps"
    _check_predictions(result, seen, delays)


@pytest.mark.parametrize("victim, complexity, width", [
    (Victim("mseq", length=6, seed=5), 6, 6),
    (Victim("mseq", length=16, seed=0xACE1), 16, 16),
    (Victim("masked", mask_width=6, seed=99), 32, 6),
    (Victim("masked", mask_width=12, seed=99), 32, 12),
])
def test_unknown_taps_lock_by_berlekamp_massey(blind, victim, complexity, width):
    # Berlekamp-Massey determines a recurrence of length L from 2L bits of one output stream;
    # the 16-step map of the 32-bit masked register has a degree-32 minimal polynomial.
    result, seen, delays = _attack(blind, victim, 400)
    assert result.locked_after == 1 + 2 * complexity + _verify(width)
    assert "Berlekamp-Massey" in result.model
    _check_predictions(result, seen, delays)


@pytest.mark.parametrize("victim", [
    Victim("keyed", mask_width=1, key=0x80000000000000000000),
    Victim("keyed", mask_width=6, key=0x0123456789ABCDEF0123, iv=7),
    Victim("keyed", mask_width=16, key=1),
    Victim("random", mask_width=3, seed=4),
    Victim("random", mask_width=10, seed=5),
])
def test_never_locks_on_unpredictable_sources(attacker, victim):
    result, _, _ = _attack(attacker, victim, 6000)
    assert result.locks == []
    assert result.locked_after is None
    # It still fires: at the measured effective PRF, from its 16th observation on.
    mean = 80 + ((1 << victim.mask_width) - 1) / 2
    assert abs(result.prf_period_cycles - mean) < 0.5 * mean


def test_linear_complexity_of_keyed_keeps_growing():
    # A keystream bit stream behaves as random bits: linear complexity about n / 2 (a linear
    # source stays at its register length: 32 for masked).
    keyed = Victim("keyed", mask_width=6, key=1).delays(2000) & 1
    masked = Victim("masked", mask_width=6, seed=0xACE1).delays(2000) & 1
    for n in (100, 500, 2000):
        assert abs(gf2.berlekamp_massey(keyed[:n])[0] - n / 2) <= 6
        assert gf2.berlekamp_massey(masked[:n])[0] == 32


def test_off_is_predicted_too(attacker):
    result, seen, delays = _attack(attacker, Victim("off"), 300)
    assert result.locked_after is not None and result.locked_after <= 1 + 48 + 2
    _check_predictions(result, seen, delays)


def test_edges_follow_the_victim_after_lock(attacker):
    victim = Victim("masked", mask_width=6, seed=77)
    starts = victim.start_cycles(3000, start=50)
    times, _ = Observer(seed=1).observe(starts)
    result = attacker.attack(times)
    lock_cycle = starts[result.locks[0].observation]
    after = result.edges[result.edges > lock_cycle]
    assert np.array_equal(after, starts[starts > lock_cycle])
    before = result.edges[result.edges <= lock_cycle]
    assert len(before) <= 1 + result.locked_after


def test_large_jitter_delays_lock_but_never_gives_wrong_predictions(attacker):
    victim = Victim("masked", mask_width=6, seed=21)
    quiet, _, _ = _attack(attacker, victim, 2000, Observer(seed=2))
    # 3 ns rms on each time: an interval rounds to the wrong cycle now and then
    noisy = Observer(jitter_s=3e-9, seed=2)
    starts = victim.start_cycles(2000, start=50)
    times, seen = noisy.observe(starts)
    misread = np.mean(np.diff(np.rint(times * noisy.clock_hz)) != np.diff(starts))
    assert 0.01 < misread < 0.5
    result = Attacker(80, jitter_s=3e-9).attack(times)
    assert result.locked_after >= quiet.locked_after
    assert result.locks[0].lost is None           # tracking tolerates the jitter it knows
    _check_predictions(result, seen, victim.delays(2000))


@pytest.mark.parametrize("missed", [0.02, 0.1])
def test_missed_pulses(attacker, missed):
    victim = Victim("masked", mask_width=6, seed=0xBEEF)
    result, seen, delays = _attack(attacker, victim, 6000, Observer(missed=missed, seed=4))
    assert result.locked_after is not None
    # A window must be free of misses: the lock comes no sooner than without them.
    assert result.locked_after >= 1 + 6 + _verify(6)
    # Once locked, a miss is recognised as such and does not drop the lock.
    assert len(result.locks) == 1 and result.locks[0].lost is None
    _check_predictions(result, seen, delays)


def test_grid_mode():
    # The phase is unknown: one reading per candidate phase; once it is right, the first pulse's
    # delay is readable too, so the lock comes one pulse sooner than in interval mode.
    victim = Victim("masked", mask_width=5, seed=0xFACE, grid=True)
    result, seen, delays = _attack(Attacker(80, grid=True), victim, 400)
    assert result.locked_after == _masked_solve_pulses(5) + _verify(5)
    _check_predictions(result, seen, delays)
    result, seen, delays = _attack(Attacker(80, grid=True, known_taps=False), victim, 400)
    assert result.locked_after == 2 * 32 + _verify(5)
    _check_predictions(result, seen, delays)
    # Misses are plain in grid mode (a pulse index skipped); a lock still needs a window free
    # of them, and keeps going across them.
    result, seen, delays = _attack(Attacker(80, grid=True), victim, 3000,
                                   Observer(missed=0.05, seed=3))
    assert result.locked_after >= _masked_solve_pulses(5) + _verify(5)
    assert len(result.locks) == 1 and result.locks[0].lost is None
    _check_predictions(result, seen, delays)


def test_bad_settings():
    with pytest.raises(ValueError, match="Period must be a whole number of at least 2"):
        Attacker(1)
    with pytest.raises(ValueError, match="at least one hypothesis"):
        Attacker(80, known_taps=False, unknown_taps=False)
    with pytest.raises(ValueError, match="Missed fraction must be below 1"):
        Observer(missed=1.0)
    with pytest.raises(ValueError, match="Observer jitter"):
        Observer(jitter_s=-1e-12)
    with pytest.raises(ValueError, match="at least two finite emission times"):
        Attacker(80).attack([1.0])
    with pytest.raises(ValueError, match="Victim source must be one of"):
        Victim("lfsr")
    with pytest.raises(ValueError, match="Mask width must be an integer from 1 to 16"):
        Victim("keyed", mask_width=17)
