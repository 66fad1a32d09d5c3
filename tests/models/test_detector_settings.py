"""The detector's settings as text with units (:mod:`fliss.sim.scene.detector_options`), and
the sweeps' study taking them by the same names (:mod:`fliss.sim.studies.interference`)."""

import math

import numpy as np
import pytest

from fliss.sim.scene import PRESETS, Detector
from fliss.sim.scene.detector_options import DetectorSettingError, detector_from
from fliss.sim.studies.interference import check_point, evaluate, scene_of


WINDOW_S = 8192 * 50e-12                # a TDC window: 2**13 codes of 50 ps


def test_each_value_is_read_with_its_unit_over_a_preset():
    # 1.4 % is 0.014, 40 ns 4e-8 s, 7 kHz 7000 Hz; what is not given stays the preset's
    detector = detector_from("spcm20a", {"afterpulsing": "1.4%", "afterpulse_tau": "40ns",
                                         "dark_count": "7kHz", "jitter_tail": "80ps",
                                         "jitter_tail_share": "12.5%", "dead_time": "22ns",
                                         "paralysable": True, "pdp": "50 %",
                                         "hot_pixels": "2%", "hot_dark_count": "1.5MHz",
                                         "jitter": "0.3ns", "crosstalk": "3.5%",
                                         "crosstalk_diagonal": "1%"})
    assert detector == Detector(
        pdp=0.5, dark_count_hz=7000.0, hot_fraction=0.02, hot_dark_count_hz=1.5e6,
        dead_time_s=22e-9, paralysable=True, jitter_fwhm_s=0.3e-9, tail_fraction=0.125,
        tail_s=80e-12, afterpulse_probability=0.014, afterpulse_s=(40e-9,),
        crosstalk_orthogonal=0.035, crosstalk_diagonal=0.01)
    assert detector_from("spcm20a", {"dark_count": "7kHz"}) == \
        PRESETS["spcm20a"].replace(dark_count_hz=7000.0)
    assert detector_from(None, {}) == Detector() == detector_from("paper")
    two = detector_from(None, {"afterpulsing": "2%", "afterpulse_tau": "20ns,200ns",
                               "afterpulse_weights": "75%,25%"})
    assert two.afterpulse_s == pytest.approx((20e-9, 200e-9))
    assert two.afterpulse_weights == pytest.approx((0.75, 0.25))


@pytest.mark.parametrize("preset, settings, style, message", [
    ("nikon", {}, "flag", "--sensor-preset nikon: unknown preset (known: paper, spcm20a, "
                          "linospad2)"),
    ("nikon", {}, "key", "sensor_preset = 'nikon': unknown preset (known: paper, spcm20a, "
                         "linospad2)"),
    (None, {"afterpulsing": "140%"}, "flag", "--afterpulsing 140%: a share is from 0 to 100 %"),
    (None, {"dark_count": "7"}, "flag", "--dark-count 7: give a unit: 7kHz or 25Hz"),
    (None, {"dark_count": "-7kHz"}, "flag",
     "--dark-count -7kHz: must be a finite rate, not negative"),
    (None, {"dead_time": "-1ns"}, "key", "dead_time = '-1ns': must be a finite time, not "
                                         "negative"),
    (None, {"dead_time": 20e-9}, "key", "dead_time = 2e-08: give it as text with its unit: "
                                        "40ns or 80ps"),
    (None, {"jitter": "100kHz"}, "flag", "--jitter 100kHz: cannot read it as a time (for "
                                         "example 40ns or 80ps)"),
    (None, {"afterpulsing": "1%"}, "flag", "--afterpulsing 1%: needs --afterpulse-tau"),
    (None, {"afterpulse_tau": "40ns"}, "flag",
     "--afterpulse-tau 40ns: does nothing without --afterpulsing"),
    (None, {"jitter_tail": "80ps"}, "key", "jitter_tail = '80ps': does nothing without "
                                           "jitter_tail_share"),
    (None, {"hot_pixels": "2%"}, "flag", "--hot-pixels 2%: needs --hot-dark-count"),
    (None, {"pdp": "0%"}, "flag", "--pdp 0%: a SPAD that detects nothing: give more than 0 %"),
    (None, {"afterpulsing": "100%", "afterpulse_tau": "40ns"}, "flag",
     "--afterpulsing 100%: must be below 100 % (an afterpulse can afterpulse again)"),
    (None, {"afterpulsing": "1%", "afterpulse_tau": "40ns,1us", "afterpulse_weights": "50%"},
     "flag", "--afterpulse-weights 50%: give one share per time of --afterpulse-tau (2)"),
    (None, {"paralysable": "yes"}, "key", "paralysable = 'yes': must be true or false"),
])
def test_a_bad_value_is_refused_in_one_line_naming_the_setting(preset, settings, style,
                                                               message):
    with pytest.raises(DetectorSettingError) as error:
        detector_from(preset, settings, style=style)
    assert str(error.value) == message


def test_the_study_takes_the_detector_by_the_option_names():
    point = check_point({"sensor_preset": "spcm20a", "dead_time": "40ns",
                         "paralysable": True})
    scene = scene_of(point, np.random.default_rng(1))
    assert scene.detector == PRESETS["spcm20a"].replace(dead_time_s=40e-9, paralysable=True)
    assert scene_of(check_point({}), np.random.default_rng(1)).detector == Detector()
    with pytest.raises(ValueError, match=r"^afterpulsing = '1\.4': give a unit: 1\.4%$"):
        check_point({"afterpulsing": "1.4"})
    with pytest.raises(ValueError, match=r"^Unknown point parameter 'crosstalk'"):
        check_point({"crosstalk": "1%"})         # one pixel: nothing to cross to


def test_dark_counts_set_in_a_sweep_point_reach_its_frames():
    # No laser echo, no ambient light, no dead time: the TDC keeps a dark count in a window
    # when the Poisson stream of rate r puts one or more in it, 1 - exp(-r W) of the windows;
    # 10 frames of 10 ms at 1 MHz are 1e5 windows.
    rate_hz, frames, windows = 2e5, 10, 100_000
    p = 1 - math.exp(-rate_hz * WINDOW_S)
    common = dict(scheme="off", aggressors=0, detections_per_pulse=0.0, background_hz=0.0,
                  frames=frames, t_int_s=0.01, dead_time="0ns")
    dark = evaluate(dict(common, dark_count="200kHz"), np.random.SeedSequence(4))
    counted = dark["background_counts_per_frame"] * frames
    assert abs(counted - windows * p) < 4.5 * math.sqrt(windows * p * (1 - p)), (counted,
                                                                                  windows * p)
    assert evaluate(common, np.random.SeedSequence(4))["background_counts_per_frame"] == 0


@pytest.mark.parametrize("text", ["40ns", "0.3 ns", "1.5e-9s", "80ps", "2us", "2µs", "1ms",
                                  "0ns", "+22ns"])
def test_times_read_as_the_host_reads_them(text):
    # The simulator cannot import fliss.host.units; the detector's settings take its forms
    from fliss.host.units import parse_time
    setting = {"dead_time": text}
    assert detector_from(None, setting).dead_time_s == pytest.approx(parse_time(text, zero=True),
                                                                     rel=1e-15)


@pytest.mark.parametrize("text", ["7kHz", "25Hz", "1.5MHz", "1e5Hz", "0.001GHz", "7 khz"])
def test_rates_read_as_the_host_reads_them(text):
    from fliss.host.units import parse_frequency
    assert detector_from(None, {"dark_count": text}).dark_count_hz == \
        pytest.approx(parse_frequency(text), rel=1e-15)
