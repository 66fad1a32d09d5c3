"""A sweep spec names the detector's settings as ``fliss board``'s options do, with the same
values (:mod:`fliss.host.sweep.spec` on the interference study)."""

import pytest

from fliss.host.sweep.spec import SpecError, parse
from fliss.sim.scene import PRESETS
from fliss.sim.scene.detector_options import SETTINGS
from fliss.sim.studies.interference import PARAMETERS, scene_of

import numpy as np


def test_a_spec_takes_the_detector_by_the_option_names(tmp_path):
    spec = parse({"parameters": {"sensor_preset": "spcm20a", "dead_time": ["22ns", "40ns"],
                                 "afterpulsing": "1.4%", "afterpulse_tau": "40ns",
                                 "paralysable": True}}, "s.toml")
    detectors = [scene_of(point, np.random.default_rng(0)).detector for point in spec.points()]
    base = PRESETS["spcm20a"].replace(afterpulse_probability=0.014, afterpulse_s=(40e-9,),
                                      paralysable=True)
    assert detectors == [base.replace(dead_time_s=22e-9), base.replace(dead_time_s=40e-9)]


def test_a_bad_detector_value_in_a_spec_is_refused_naming_the_file_and_the_point():
    with pytest.raises(SpecError) as error:
        parse({"parameters": {"afterpulsing": "140%", "afterpulse_tau": "40ns"}}, "s.toml")
    assert str(error.value) == ('s.toml: point {"afterpulse_tau":"40ns","afterpulsing":"140%"}: '
                                'afterpulsing = \'140%\': a share is from 0 to 100 %')
    with pytest.raises(SpecError, match=r"unknown preset \(known: paper, spcm20a, linospad2\)"):
        parse({"parameters": {"sensor_preset": "nikon"}}, "s.toml")


def test_a_point_without_them_keeps_its_key():
    # The detector's parameters default to None and are left out of a point not giving them:
    # it holds the parameters it held before they existed, so its key and random streams too.
    spec = parse({"parameters": {"aggressors": 2}}, "s.toml")
    detector = {"sensor_preset"} | {setting.name for setting in SETTINGS}
    assert set(spec.points()[0]) == set(PARAMETERS) - detector
    given = parse({"parameters": {"aggressors": 2, "dark_count": "1kHz"}}, "s.toml")
    assert set(given.points()[0]) == set(PARAMETERS) - detector | {"dark_count"}
