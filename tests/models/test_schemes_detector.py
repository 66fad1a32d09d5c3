"""The schemes study takes the detector as the interference study and ``fliss board`` do: by the
names of :mod:`fliss.sim.scene.detector_options` with units, in its sweep specs; the settings a
spec gives reach the frames as their closed forms say, and a bad one is refused naming the file
and the point."""

import math

import numpy as np
import pytest

from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.hdl.event import TDC_LSB_S
from fliss.host.sweep.spec import SpecError, parse
from fliss.sim.studies.schemes import check_point, evaluate
from fliss.sim.studies.schemes.frame import simulate_frame, window_codes
from fliss.sim.studies.schemes.study import detector_of

_MODEL = "fliss.sim.studies.schemes:evaluate"


def _points(parameters):
    return parse({"model": _MODEL, "parameters": parameters}, "s.toml").points()


def test_a_dark_count_rate_of_the_spec_fills_its_windows_as_poisson_says():
    # No echo, no ambient light, one camera at a fixed period: a window of W holds a dark count
    # (the single-hit TDC's one event) with probability 1 - exp(-r W); the 20 ns dead time
    # hides one only when the window's photons all follow a count before it within 20 ns
    # (about (r tau)^2, 4e-4 here, below the bound)
    rate, frames = 1e6, 4
    point, = _points({"scheme": "none", "background_hz": 0.0, "detections_per_frame": 0.0,
                      "dark_count": "1MHz", "frames": frames})
    result = evaluate(point, np.random.SeedSequence(21))
    windows = result["windows_per_frame"] * frames
    width = window_codes(check_point(point)) * TDC_LSB_S
    assert width < 80 / DEFAULT_CLOCK_HZ          # the TDC's window ends before the next pulse
    expected = 1 - math.exp(-rate * width)
    measured = result["background_events_per_frame"] * frames / windows
    bound = 4 * math.sqrt(expected * (1 - expected) / windows)
    assert abs(measured - expected) < bound, (measured, expected, bound)


@pytest.mark.parametrize("paralysable", [False, True])
def test_a_dead_time_of_the_spec_sets_the_count_rate(paralysable):
    # A Poisson rate r on one SPAD of dead time tau counts r / (1 + r tau) (non-paralysable) or
    # r exp(-r tau) (paralysable); r tau = 1 here, so the two differ by a third
    rate, dead = 2e7, 50e-9
    parameters = {"scheme": "none", "background_hz": 0.0, "detections_per_frame": 0.0,
                  "sensor_preset": "spcm20a", "pdp": "100%", "dark_count": "20MHz",
                  "dead_time": "50ns"}
    if paralysable:
        parameters["paralysable"] = True
    point, = _points(parameters)
    point = check_point(point)
    detector = detector_of(point)
    point.update(_tof_lsb=0.0, _detections_per_pulse=0.0)
    frame = simulate_frame(point, detector, np.random.default_rng(22))
    length = window_codes(point)
    span = (point["t_int_s"] / TDC_LSB_S + 3.0 * length + dead / TDC_LSB_S) * TDC_LSB_S
    counted = rate * math.exp(-rate * dead) if paralysable else rate / (1 + rate * dead)
    expected = counted * span
    assert abs(frame.counts[1] - expected) < 4 * math.sqrt(expected), (frame.counts[1], expected)


def test_the_coincidence_window_is_held_to_the_dead_time_the_spec_gives():
    with pytest.raises(SpecError, match=r"at most the dead time \(10 ns\)"):
        _points({"spads": 4, "coincidence": 2, "coincidence_window_ns": 15.0,
                 "dead_time": "10ns"})
    point, = _points({"spads": 4, "coincidence": 2, "coincidence_window_ns": 15.0,
                      "dead_time": "22ns"})
    assert detector_of(check_point(point)).dead_time_s == 22e-9


def test_a_bad_detector_value_in_a_schemes_spec_is_refused_naming_the_file_and_the_point():
    with pytest.raises(SpecError) as error:
        _points({"afterpulsing": "140%", "afterpulse_tau": "40ns"})
    assert str(error.value) == ('s.toml: point {"afterpulse_tau":"40ns","afterpulsing":"140%"}: '
                                'afterpulsing = \'140%\': a share is from 0 to 100 %')
    with pytest.raises(SpecError, match=r"s.toml: point .*dead_time = 22: give it as text"):
        _points({"dead_time": 22})
    with pytest.raises(SpecError, match=r"unknown preset \(known: paper, spcm20a, linospad2\)"):
        _points({"sensor_preset": "nikon"})
    with pytest.raises(SpecError, match=r"crosstalk = '3%': does nothing with one SPAD"):
        _points({"crosstalk": "3%"})
