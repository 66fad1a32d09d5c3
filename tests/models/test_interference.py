"""Aggressors on their own oscillators, the victim's fine delay step, and evaluate()."""

import math

import numpy as np
import pytest

from fliss.sim.models import delay as delay_model
from fliss.sim.models import scheduler
from fliss.sim.studies.interference import PARAMETERS, evaluate
from fliss.sim.scene import Aggressor, Scene, acquire
from fliss.sim.scene.pulses import EdgeSchedule


LSB_S = 50e-12
CYCLE_S = 12.5e-9


def aggressor_only(**aggressor):
    victim = scheduler.Settings(period=80)
    return Scene(victim=victim, detections_per_pulse=0.0, background_hz=0.0,
                 aggressors=(Aggressor(period_cycles=80, detections_per_pulse=0.3, **aggressor),))


@pytest.mark.parametrize("ppm", [50.0, -50.0, 20.0])
def test_an_aggressor_off_frequency_walks_at_the_rate_its_offset_implies(ppm):
    # Its period is 80 / (1 + ppm 1e-6) victim cycles: it arrives 80 * ppm 1e-6 cycles earlier
    # at every pulse, 1.0 TDC code per pulse at 50 ppm (80 * 5e-5 * 12.5 ns / 50 ps)
    expected = -80 * ppm * 1e-6 * CYCLE_S / LSB_S
    result = acquire(aggressor_only(ppm=ppm, offset_s=200e-9), 2e-3, 1, seed=1, keep_events=True)
    events = result.events[0]
    slope = np.polyfit(events["pulse"].astype(float), events["timestamp"].astype(float), 1)[0]
    assert len(events) > 300
    assert slope == pytest.approx(expected, abs=0.01)


def test_a_locked_aggressor_does_not_walk():
    events = acquire(aggressor_only(offset_s=200e-9), 2e-3, 1, seed=1, keep_events=True).events[0]
    slope = np.polyfit(events["pulse"].astype(float), events["timestamp"].astype(float), 1)[0]
    assert abs(slope) < 0.01


def test_phase_jitter_widens_the_aggressor_peak_in_quadrature():
    sigma_pulse = math.hypot(2.1e-9, 100e-12) / (2 * math.sqrt(2 * math.log(2)))
    for jitter in (0.0, 1e-9, 3e-9):
        events = acquire(aggressor_only(offset_s=200e-9, jitter_s=jitter), 5e-3, 1, seed=2,
                         keep_events=True).events[0]
        spread = np.std(events["timestamp"].astype(float)) * LSB_S
        # ~1500 photons: the standard deviation is known to about 2 %
        assert spread == pytest.approx(math.hypot(sigma_pulse, jitter), rel=0.06)


@pytest.mark.parametrize("grid", [False, True])
@pytest.mark.parametrize("fine_step", [1, 2, 16])
def test_the_fine_step_divides_the_gateware_delays(fine_step, grid):
    settings = scheduler.Settings(mode=delay_model.DelayMode.MSEQ, length=6, period=80,
                                  grid=grid, seed=5)
    delays = delay_model.delays("mseq", 300, length=6, seed=5)
    schedule = EdgeSchedule(settings, 100, fine_step=fine_step)
    edges = np.concatenate([schedule() for _ in range(3)])
    nominal = scheduler.fire_cycles(np.zeros(300, dtype=np.int64), 80, grid=grid)
    if grid:
        expected = nominal + delays / fine_step
    else:
        # Interval: pulse k waits for the delays of all pulses up to k
        expected = nominal + np.cumsum(delays) / fine_step
    assert np.allclose(edges[:300], expected + scheduler.LATENCY)


def test_ten_aggressors_at_once_each_keep_their_photons():
    aggressors = tuple(Aggressor(period_cycles=80, offset_s=20e-9 * i, ppm=5.0 * i,
                                 detections_per_pulse=0.02) for i in range(12))
    scene = Scene(victim=scheduler.Settings(period=80), aggressors=aggressors)
    result = acquire(scene, 1e-3, 1, seed=3)
    generated = result.counts[0, 2:, 0]
    # 1000 pulses at 0.02 each: 20 +- 4.5 photons per aggressor
    assert len(generated) == 12 and np.all(np.abs(generated - 20) < 20)


def test_scene_refuses_bad_oscillators_and_steps():
    with pytest.raises(ValueError, match="frequency offset"):
        Aggressor(period_cycles=80, ppm=math.inf)
    with pytest.raises(ValueError, match="phase jitter"):
        Aggressor(period_cycles=80, jitter_s=-1e-9)
    with pytest.raises(ValueError, match="Fine delay step must be one of"):
        Scene(fine_step=3)


def quick(**point):
    return dict({"frames": 12, "frames_per_run": 4, "t_int_s": 2e-3}, **point)


def test_evaluate_is_deterministic_in_its_seed():
    point = quick(aggressors=3, aggressor_kind="fliss")
    seed = np.random.SeedSequence(7)
    first = evaluate(point, seed)
    assert evaluate(point, seed) == first
    assert evaluate(point, np.random.SeedSequence(7)) == first
    assert evaluate(point, np.random.SeedSequence(8)) != first


def test_evaluate_returns_flat_scalars_and_consistent_counts():
    result = evaluate(quick(), np.random.SeedSequence(1))
    for key in ("frames", "miss", "ghost", "wrong_depth", "p_miss", "p_miss_lo", "p_miss_hi",
                "p_ghost", "p_wrong_depth_lo", "p_wrong_depth_hi", "depth_error_mean_m",
                "depth_error_rms_m", "s_db", "curve_threshold", "curve_p_detect",
                "curve_false_per_frame"):
        assert key in result
    assert all(value is None or isinstance(value, (bool, int, float, str))
               for value in result.values())
    assert result["frames"] == 12
    assert result["p_ghost"] == result["ghost"] / 12
    assert result["p_ghost_lo"] <= result["p_ghost"] <= result["p_ghost_hi"]


def test_equal_power_locked_aggressor_beats_fliss_off_but_not_mseq():
    # The paper's case: at the victim's effective PRF, without FLISS the aggressor's peak is as
    # high as the victim's; with mseq L = 6 it spreads over the clock comb (a ghost is left in
    # about one frame of 500: seeds 0 to 59, 8 frames each, gave one)
    common = dict(aggressor_kind="locked", offset_ns=60.0, frames=8, frames_per_run=8)
    off = evaluate(dict(common, scheme="off"), np.random.SeedSequence(3))
    mseq = evaluate(dict(common, scheme="mseq"), np.random.SeedSequence(3))
    assert off["ghost"] == 8 and abs(off["s_db"]) < 1.5
    assert mseq["ghost"] <= 1 and mseq["s_db"] > 10


@pytest.mark.parametrize("point, message", [
    ({"schem": "off"}, "Unknown point parameter 'schem'"),
    ({"scheme": "fast"}, "scheme must be one of off, mseq, masked"),
    ({"fine_step": 3}, "fine_step must be one of 1, 2, 4, 8, 16"),
    ({"aggressors": -1}, "aggressors must be an integer from 0 to 64"),
    ({"aggressor_kind": "evil"}, "aggressor_kind must be one of free, fliss, locked"),
    ({"t_int_s": 0}, "t_int_s must be a finite number > 0"),
    ({"frames": 1.5}, "frames must be an integer"),
    ({"distance_m": 100.0}, "distance_m must be a finite number"),
    ({"scheme": "mseq", "length": 7, "grid": True, "period_cycles": 100},
     "Victim settings of the point: Grid mode needs"),
])
def test_bad_points_are_refused_with_one_line(point, message):
    with pytest.raises(ValueError, match=message) as error:
        evaluate(point, np.random.SeedSequence(0))
    assert "\n" not in str(error.value)


def test_every_parameter_has_a_default_that_evaluates():
    assert set(PARAMETERS) >= {"scheme", "fine_step", "aggressors", "aggressor_power",
                               "ppm_spread", "jitter_ps", "aggressor_kind", "t_int_s",
                               "threshold_sigma", "frames", "distance_m", "background_hz"}
    with pytest.raises(ValueError, match="SeedSequence"):
        evaluate({}, 1)


@pytest.mark.parametrize("fine_step", [1, 4, 16])
def test_a_locked_aggressor_lands_on_the_comb_of_the_victim_delay_step(fine_step):
    # Grid mode: the victim's start k is at k T + R[k] / n cycles, the locked aggressor at
    # k T + offset, so its photons sit at offset - R[k] / n cycles: a comb of step 250 / n codes,
    # every tooth (every value of R, 1 to 63 for mseq L = 6) equally often
    victim = scheduler.Settings(mode=delay_model.DelayMode.MSEQ, length=6, period=80, grid=True)
    aggressor = Aggressor(period_cycles=80, offset_s=300e-9, fwhm_s=0.1e-9,
                          detections_per_pulse=0.5)
    scene = Scene(victim=victim, detections_per_pulse=0.0, background_hz=0.0, dead_time_s=0.0,
                  aggressors=(aggressor,), fine_step=fine_step, keep="first")
    events = acquire(scene, 5e-3, 1, seed=4, keep_events=True).events[0]
    step = 250 / fine_step
    first = (300e-9 + scene.tof_s) / LSB_S           # the tooth of R = 0
    teeth = (first - events["timestamp"] - 0.5) / step
    residual = teeth - np.round(teeth)
    assert np.std(residual) * step < 3.0           # photons spread by 2.6 codes RMS
    occupied = np.unique(np.round(teeth))
    # R = 0 … 62, those whose tooth falls in the window
    assert occupied.min() == 0 and len(occupied) == min(63, int(first // step) + 1)


def test_overwriting_by_aggressors_keeps_what_poisson_statistics_predict():
    # The last-photon TDC keeps the echo when no photon is detected after it in the same
    # window: after the dead time, until the end of the 409.6 ns window. Free-running
    # aggressors at 1 MHz spread uniformly: each brings 0.05 / 1000 ns photons, background
    # 1e5 / s; so P(kept) = exp(-(8 * 0.05e-3 + 1e-4) * (409.6 - 26.7 - 20))
    expected = math.exp(-(8 * 0.05e-3 + 1e-4) * (409.6 - 26.7 - 20))
    result = evaluate(dict(scheme="off", aggressors=8, frames=60, frames_per_run=6),
                      np.random.SeedSequence(11))
    # About 21000 echo photons: the kept fraction is known to 0.003
    assert result["signal_recorded"] == pytest.approx(expected, abs=0.012)


@pytest.mark.parametrize("seed", [1, 0x9E3779B9, (1 << 32) - 1])
def test_masked_delays_for_many_seeds_are_the_gateware_sequence(seed):
    from fliss.sim.models.delay import MaskedDelays
    stream = MaskedDelays(5, seed, 700)
    got = np.concatenate([stream.block() for _ in range(3)])
    assert np.array_equal(got, delay_model.delays("masked", 2100, mask_width=5, seed=seed))


def test_detection_curve_falls_as_the_threshold_rises_and_no_aggressor_means_no_ghost():
    import json
    alone = evaluate(quick(aggressors=0), np.random.SeedSequence(2))
    assert alone["ghost"] == 0 and alone["miss"] == 0 and alone["aggressor_counts_per_frame"] == 0
    result = evaluate(quick(scheme="off", aggressors=4, aggressor_kind="locked"),
                      np.random.SeedSequence(2))
    thresholds = json.loads(result["curve_threshold"])
    detect = json.loads(result["curve_p_detect"])
    false = json.loads(result["curve_false_per_frame"])
    assert len(thresholds) == len(detect) == len(false)
    assert np.all(np.diff(thresholds) > 0)
    assert np.all(np.diff(detect) <= 0) and np.all(np.diff(false) <= 0)
    assert detect[0] == 1.0 and false[0] > 0
