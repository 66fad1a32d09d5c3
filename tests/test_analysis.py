"""Histogram analysis against histograms built here with known peaks and Poisson noise."""

import math

import numpy as np
import pytest

from fliss.host import analysis


BIN_S = 50e-12
CODES = 8192
FWHM_S = 2.1e-9
SIGMA_BINS = FWHM_S / BIN_S / (2 * math.sqrt(2 * math.log(2)))


def expected_histogram(level, peaks):
    """Mean counts per code: a flat level plus Gaussians given as (position_s, height)."""
    centres = np.arange(CODES) + 0.5
    mean = np.full(CODES, float(level))
    for position_s, height in peaks:
        mean += height * np.exp(-0.5 * ((centres - position_s / BIN_S) / SIGMA_BINS) ** 2)
    return mean


def noisy(mean, seed=0):
    return np.random.default_rng(seed).poisson(mean)


def test_background_level_ignores_the_peaks():
    levels = []
    for seed in range(5):
        histogram = noisy(expected_histogram(3.0, [(26.7e-9, 300), (101.7e-9, 80)]), seed)
        levels.append(analysis.background(histogram))
    # Mean of about 7800 Poisson(3) codes: standard error 0.02
    assert np.mean(levels) == pytest.approx(3.0, abs=0.03)


def test_noiseless_peaks_are_measured_exactly():
    histogram = expected_histogram(0.5, [(26.7e-9, 400), (101.7e-9, 40)])
    peaks = analysis.find_peaks(histogram)
    assert len(peaks) == 2
    victim, aggressor = peaks                       # highest first
    assert victim.position_s == pytest.approx(26.7e-9, abs=5e-12)
    assert aggressor.position_s == pytest.approx(101.7e-9, abs=5e-12)
    # Smoothing lowers the height by sigma / sqrt(sigma**2 + 5**2) and its width is removed
    lowered = SIGMA_BINS / math.hypot(SIGMA_BINS, 5.0)
    assert victim.height == pytest.approx(400 * lowered, rel=2e-3)
    assert aggressor.height == pytest.approx(40 * lowered, rel=2e-3)
    assert victim.fwhm_s == pytest.approx(FWHM_S, rel=0.01)
    assert aggressor.fwhm_s == pytest.approx(FWHM_S, rel=0.01)


def test_noisy_peaks_keep_position_and_width():
    positions, widths = [], []
    for seed in range(10):
        histogram = noisy(expected_histogram(0.5, [(26.7e-9, 100)]), seed)
        (peak,) = analysis.find_peaks(histogram)
        positions.append(peak.position_s)
        widths.append(peak.fwhm_s)
    assert np.mean(positions) == pytest.approx(26.7e-9, abs=20e-12)
    assert np.mean(widths) == pytest.approx(FWHM_S, rel=0.03)


def test_no_peaks_in_pure_background():
    for seed in range(5):
        assert analysis.find_peaks(noisy(np.full(CODES, 2.0), seed)) == []


def test_suppression_takes_the_highest_aggressor_peak():
    lowered = SIGMA_BINS / math.hypot(SIGMA_BINS, 5.0)
    histogram = expected_histogram(0.2, [(26.7e-9, 1000), (80e-9, 100), (150e-9, 50),
                                         (300e-9, 400)])
    # The peak at 300 ns is in neither reference: not an aggressor peak
    result = analysis.suppression(histogram, 26.7e-9, [80.1e-9, 150e-9])
    assert not result.limited
    assert result.pv == pytest.approx(1000 * lowered, rel=2e-3)
    assert result.pa == pytest.approx(100 * lowered, rel=2e-3)
    assert result.s_db == pytest.approx(10.0, abs=0.01)
    assert len(result.aggressors) == 2


def test_suppression_without_aggressor_peak_is_a_lower_bound():
    histogram = expected_histogram(4.0, [(26.7e-9, 500)])
    result = analysis.suppression(histogram, 26.7e-9, [101.7e-9])
    assert result.limited and result.aggressors == ()
    # Pa is the detection threshold: 5 noise deviations of the smoothed background
    kernel = np.exp(-0.5 * (np.arange(-20, 21) / 5.0) ** 2)
    kernel /= kernel.sum()
    threshold = 5 * math.sqrt(4.0 * np.sum(kernel ** 2))
    assert result.pa == pytest.approx(threshold, rel=1e-6)
    assert result.s_db == pytest.approx(10 * math.log10(result.pv / threshold))


def test_identify_by_reference_positions():
    peaks = [analysis.Peak(0, 26.7e-9, 2e-9, 50.0), analysis.Peak(0, 27.5e-9, 2e-9, 10.0),
             analysis.Peak(0, 101.0e-9, 2e-9, 5.0), analysis.Peak(0, 200e-9, 2e-9, 3.0)]
    victim, aggressors, others = analysis.identify(peaks, 26.5e-9, [101.7e-9])
    assert victim.height == 50.0
    assert [peak.height for peak in aggressors] == [5.0]
    assert [peak.height for peak in others] == [10.0, 3.0]


def test_relative_deviation_and_statistics():
    assert np.allclose(analysis.relative_deviation([101.0, 99.0], 100.0), [0.01, -0.01])
    mean, std = analysis.mean_std([1.0, 2.0, 3.0, math.nan])
    assert mean == 2.0 and std == pytest.approx(1.0)
    assert analysis.mean_std([4.0]) == (4.0, 0.0)


def test_bad_input_raises_with_a_clear_message():
    with pytest.raises(ValueError, match=r"^Peak heights must be positive, not Pv=1.0, Pa=0.0$"):
        analysis.suppression_db(1.0, 0.0)
    with pytest.raises(ValueError, match=r"^A histogram must be a 1-D array of at least 3 bins, "
                                         r"not of shape \(2, 2\)$"):
        analysis.find_peaks(np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"^No victim peak within 1.5 ns of 50 ns$"):
        analysis.suppression(expected_histogram(1.0, [(26.7e-9, 100)]), 50e-9, [])
    with pytest.raises(ValueError, match=r"^The reference value must not be zero$"):
        analysis.relative_deviation([1.0], 0.0)
