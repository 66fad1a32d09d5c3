"""The keyed victim and the predicting aggressor of the interference model."""

import math

import numpy as np
import pytest

from fliss.sim.studies.attack_scene import Victim
from fliss.sim.studies.interference import evaluate, scene_of, check_point
from fliss.sim.studies.predicting_aggressor import attack_edges, victim_starts
from fliss.sim.scene import time_of_flight


def ten_ms(**point):
    return dict({"frames": 12, "frames_per_run": 1, "t_int_s": 0.01, "aggressors": 1,
                 "aggressor_power": 1.0}, **point)


def test_the_keyed_victim_runs_the_trivium_delays_of_a_key_drawn_from_the_seed():
    point = check_point({"scheme": "keyed", "mask_width": 6})
    first = scene_of(point, np.random.default_rng(1)).victim
    again = scene_of(point, np.random.default_rng(1)).victim
    other = scene_of(point, np.random.default_rng(2)).victim
    assert first.key == again.key != other.key and first.iv == 0 and first.key >= 1 << 32
    # The scene's starts are those of the Trivium delays of that key (sim/studies/attack_scene.py)
    expected = Victim("keyed", mask_width=6, key=first.key, iv=0).start_cycles(3000)
    assert np.array_equal(victim_starts(first, int(expected[-2]) + 1), expected)
    fixed = scene_of(check_point({"scheme": "keyed", "victim_seed": 99}),
                     np.random.default_rng(1)).victim
    assert fixed.key == 99


@pytest.mark.parametrize("scheme", ["mseq", "masked"])
def test_a_predicting_aggressor_injects_a_ghost_as_strong_as_fliss_off(scheme):
    # After the lock its pulses arrive a fixed time after every TDC start: a peak of as many
    # photons as the echo (S ~ 0 dB, as a locked aggressor against FLISS off), reported in
    # every frame, and the strongest peak about half the time (two equal peaks; the ghost's
    # later photons overwrite some of the echo's). The locked kind at the same power spreads.
    predicting = evaluate(ten_ms(scheme=scheme, aggressor_kind="predicting"),
                          np.random.SeedSequence(5))
    locked = evaluate(ten_ms(scheme=scheme, aggressor_kind="locked"), np.random.SeedSequence(5))
    assert predicting["attack_locked_runs"] == 12
    # docs/security.md: 10 (mseq L=6) and 15 (masked Wm=6) pulses, more when the delays seen
    # are narrow (more checks)
    theory = {"mseq": 10, "masked": 15}[scheme]
    assert theory <= predicting["attack_locked_after_mean"] < 2 * theory
    assert predicting["ghost"] == 12 and abs(predicting["s_db"]) < 1.5
    assert predicting["wrong_depth"] >= 3
    assert locked["ghost"] == 0 and locked["wrong_depth"] == 0 and locked["s_db"] > 10


def test_a_ghost_stronger_than_the_echo_wins_every_frame():
    # Four times the echo's photons at 20 m: always the strongest peak, the echo still found
    point = check_point(ten_ms(scheme="mseq", aggressor_kind="predicting", frames=4,
                               ghost_m=20.0, aggressor_power=4.0))
    aggressor = scene_of(point, np.random.default_rng(0)).aggressors[0]
    assert aggressor.tof_s == time_of_flight(20.0) and aggressor.offset_s == 0.0
    result = evaluate(point, np.random.SeedSequence(2))
    assert result["wrong_depth"] == 4 and result["miss"] == 0


def binomial_two_sided(k, n):
    """P-value of ``k`` successes of ``n`` fair coin tosses, two-sided (exact)."""
    if n == 0:
        return 1.0
    probabilities = [math.comb(n, i) / 2 ** n for i in range(n + 1)]
    return min(1.0, sum(p for p in probabilities if p <= probabilities[k] * (1 + 1e-9)))


def test_against_a_keyed_victim_it_never_locks_and_is_the_locked_kind():
    # Never locked, it fires at the PRF it measured, like the locked aggressor. Both kinds'
    # wrong frames then come from one proportion: given K wrong frames in all, the predicting
    # kind's share is Binomial(K, 1/2) (equal frame counts); refuse below a 1e-3 p-value. A
    # lock (P(wrong) ~ 0.6, as above) would give >= 11 of 20 frames against 0: p < 1e-3.
    point = ten_ms(scheme="keyed", frames=20)
    predicting = evaluate(dict(point, aggressor_kind="predicting"), np.random.SeedSequence(3))
    locked = evaluate(dict(point, aggressor_kind="locked"), np.random.SeedSequence(3))
    assert predicting["attack_locked_runs"] == 0
    assert predicting["attack_locked_after_mean"] is None
    k, total = predicting["wrong_depth"], predicting["wrong_depth"] + locked["wrong_depth"]
    assert binomial_two_sided(k, total) >= 1e-3


def test_the_attack_triggers_are_the_predicted_starts_after_the_lock():
    settings = scene_of(check_point({"scheme": "masked", "victim_seed": 12345}),
                        np.random.default_rng(0)).victim
    end = 200_000
    edges, after = attack_edges(settings, end, phase_cycles=37, seed=1)
    starts = victim_starts(settings, end)
    assert after == 15
    locked = edges[edges > starts[after - 1]]
    assert np.array_equal(locked, starts[after:after + len(locked)])
    assert len(locked) >= len(starts) - after - 2
    # Before the lock: the PRF train, 37 cycles late
    assert np.all(np.diff(edges) > 0)


@pytest.mark.parametrize("point, message", [
    ({"aggressor_kind": "predicting", "fine_step": 2},
     "The predicting aggressor reads whole clock cycles: it needs fine_step 1, not 2"),
    ({"ghost_m": -1.0}, "ghost_m must be a finite number >= 0"),
    ({"ghost_m": "far"}, "ghost_m must be a finite number >= 0"),
    ({"scheme": "keyed", "mask_width": 17}, "mask_width must be an integer from 1 to 16"),
])
def test_bad_predicting_points_are_refused_with_one_line(point, message):
    with pytest.raises(ValueError, match=message) as error:
        evaluate(point, np.random.SeedSequence(0))
    assert "\n" not in str(error.value)


def test_a_locked_aggressor_runs_at_the_keyed_victim_s_effective_prf():
    # Uniform 6-bit delays average 63 / 2 cycles: T + E(R) = 111.5 cycles
    point = check_point({"scheme": "keyed", "mask_width": 6, "aggressor_kind": "locked"})
    assert scene_of(point, np.random.default_rng(0)).aggressors[0].period_cycles == 111.5
    own = check_point({"scheme": "keyed", "mask_width": 5, "aggressor_kind": "fliss"})
    aggressor = scene_of(own, np.random.default_rng(0)).aggressors[0]
    assert aggressor.settings().keyed and aggressor.mask_width == 5 and aggressor.key >= 1
