"""Decision metrics of sim/studies/detection.py on synthetic histograms with known answers."""

import math

import numpy as np
import pytest

from fliss.analysis import peaks
from fliss.sim.studies import detection

from test_analysis import FWHM_S, expected_histogram     # the analysis tests' histograms


TOF_S = 26.7e-9


def judge(mean, seed=None, **options):
    counts = mean if seed is None else np.random.default_rng(seed).poisson(mean)
    return detection.classify(counts, TOF_S, FWHM_S, **options)


def test_target_alone_is_found_at_its_depth():
    for seed in range(5):
        frame = judge(expected_histogram(0.05, [(TOF_S, 10.0)]), seed)
        assert not frame.miss and not frame.ghost and not frame.wrong_depth
        # The maximum of the smoothed peak stays within a third of the FWHM (0.7 ns, 10 cm)
        assert abs(frame.depth_error_m) < 0.1


def test_depth_error_is_the_distance_of_a_shifted_peak():
    # A noiseless peak 1 ns late: 15 cm of depth (c t / 2)
    frame = judge(expected_histogram(0.0, [(TOF_S + 1e-9, 10.0)]))
    assert frame.depth_error_m == pytest.approx(0.5 * 299_792_458 * 1e-9, abs=0.004)


def test_a_stronger_peak_elsewhere_is_a_wrong_depth_and_a_ghost():
    frame = judge(expected_histogram(0.05, [(TOF_S, 10.0), (150e-9, 20.0)]), 1)
    assert frame.ghost and frame.wrong_depth and not frame.miss
    assert 10 * math.log10(frame.target_height / frame.other_height) == \
        pytest.approx(10 * math.log10(0.5), abs=0.3)


def test_a_weaker_peak_elsewhere_is_a_ghost_only():
    frame = judge(expected_histogram(0.05, [(TOF_S, 10.0), (150e-9, 4.0)]), 2)
    assert frame.ghost and not frame.wrong_depth and not frame.miss


def test_a_peak_beyond_three_fwhm_is_not_the_target():
    # 3 FWHM is 6.3 ns: a peak 8 ns away is a miss and a wrong depth, one 5 ns away is a hit
    assert judge(expected_histogram(0.0, [(TOF_S + 8e-9, 10.0)])).wrong_depth
    assert judge(expected_histogram(0.0, [(TOF_S + 8e-9, 10.0)])).miss
    assert not judge(expected_histogram(0.0, [(TOF_S + 5e-9, 10.0)])).miss


def test_nothing_above_the_threshold_is_a_miss_but_no_wrong_depth():
    frame = judge(expected_histogram(0.05, []), 3)
    assert frame.miss and not frame.ghost and not frame.wrong_depth
    assert math.isnan(frame.depth_error_m)


def test_the_threshold_decides_what_is_detected():
    # Smoothed height about 3 counts: detected at 5 sigma (the 1-count floor) ...
    mean = expected_histogram(1.0, [(TOF_S, 3.0)])
    assert not judge(mean, threshold_sigma=5.0).miss
    # ... not when the threshold asks for more noise deviations than the peak has
    sigma = peaks.noise_sigma(1.0)
    assert judge(mean, threshold_sigma=3.5 / sigma).miss


def test_wilson_interval_matches_the_formula_worked_by_hand():
    # 0 of 10: upper bound z^2 / (n + z^2)
    low, high = detection.wilson(0, 10)
    assert low == 0.0 and high == pytest.approx(3.8415 / 13.8415, rel=1e-4)
    # 5 of 10: symmetric, 0.2366 to 0.7634 (published tables)
    assert detection.wilson(5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    with pytest.raises(ValueError, match="successes <= trials"):
        detection.wilson(11, 10)


def test_wilson_interval_covers_the_true_proportion_about_95_percent_of_the_time():
    rng = np.random.default_rng(4)
    hits = rng.binomial(200, 0.03, 2000)
    covered = np.mean([lo <= 0.03 <= hi for lo, hi in (detection.wilson(k, 200) for k in hits)])
    assert 0.93 <= covered <= 0.98


def test_detection_curve_counts_targets_and_false_peaks_by_score():
    frames = [detection.Frame(False, True, False, 0.0, 1.0, 1.0, 50.0, np.array([10.0, 30.0])),
              detection.Frame(False, False, False, 0.0, 1.0, 1.0, 20.0, np.array([])),
              detection.Frame(True, True, True, math.nan, 0.0, 1.0, 0.0, np.array([5.0]))]
    detect, false = detection.detection_curve(frames, [4.0, 15.0, 25.0, 60.0])
    assert detect.tolist() == pytest.approx([2 / 3, 2 / 3, 1 / 3, 0.0])
    assert false.tolist() == pytest.approx([1.0, 1 / 3, 1 / 3, 0.0])


def test_curve_scores_agree_with_the_threshold_decision():
    # Detected at threshold k exactly when the score is above k
    for seed in range(4):
        mean = expected_histogram(0.3, [(TOF_S, 2.0 + seed), (120e-9, 1.5 + seed)])
        counts = np.random.default_rng(seed).poisson(mean)
        scored = detection.classify(counts, TOF_S, FWHM_S, floor_sigma=1.0)
        for k in (3.0, 6.0, 10.0, 20.0):
            frame = detection.classify(counts, TOF_S, FWHM_S, threshold_sigma=k)
            assert frame.miss == (scored.target_score <= k)
            assert frame.ghost == bool((scored.other_scores > k).any())


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="1-D array"):
        detection.classify(np.zeros((2, 2)), TOF_S, FWHM_S)
    with pytest.raises(ValueError, match="must be positive"):
        detection.classify(np.zeros(100), TOF_S, 0.0)
