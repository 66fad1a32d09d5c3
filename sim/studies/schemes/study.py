"""One point of the schemes study: :data:`PARAMETERS`, :func:`check_point`, :func:`evaluate`
(see :mod:`fliss.sim.studies.schemes` for the model and the parameters)."""

import math

import numpy as np

from ....hdl.clock import DEFAULT_CLOCK_HZ
from ...models import delay as _delay
from ...models import scheduler as _scheduler
from ...scene.description import SPEED_OF_LIGHT, TDC_CODES, time_of_flight
from ...scene.detector_options import (SETTINGS as _DETECTOR_SETTINGS, DetectorSettingError,
                                       detector_from)
from ....hdl.event import TDC_LSB_S
from ..detection import classify, proportion as _proportion
from ..parameters import choice as _choice, filled, integer as _integer, real as _real
from .emitters import EMISSIONS, LSB_PER_CYCLE, golomb_code, mean_period_cycles
from .frame import FWHM_S, simulate_frame, window_codes


__all__ = ["PARAMETERS", "REFERENCE_DETECTIONS", "check_point", "detector_of", "evaluate"]


#: FLISS's echo per 10 ms frame at the interference study's defaults: 0.05 detections a pulse,
#: ``mseq`` L = 6 at T = 80 cycles (a mean period of 111 cycles, 7207 pulses a frame).
REFERENCE_DETECTIONS = round(0.05 * 0.01 * DEFAULT_CLOCK_HZ / 111, 1)

#: Every point parameter with its default (see :mod:`fliss.sim.studies.schemes`).
PARAMETERS = {
    "scheme": "fliss",
    "delay_mode": "mseq",
    "length": 6,
    "mask_width": 6,
    "period_cycles": 80,
    "hop_periods": 32,
    "hop_step_cycles": 2,
    "hop_dwell": 256,
    "code_chips": 4,
    "code_slots": 16,
    "code_slot_cycles": 2,
    "spads": 1,
    "coincidence": 1,
    "coincidence_window_ns": 2.0,
    "multi_hit": False,
    "keep": "last",
    "cameras": 1,
    "aggressor_power": 1.0,
    "ppm_spread": 50.0,
    "t_int_s": 0.01,
    "detections_per_frame": REFERENCE_DETECTIONS,
    "background_hz": 1e5,
    "distance_m": 4.0,
    "threshold_sigma": 5.0,
    "frames": 200,
    # The detector, by the names of fliss board's options (None: not given; the paper's sensor)
    "sensor_preset": "paper",
    **{setting.name: None for setting in _DETECTOR_SETTINGS},
}

_DELAY_MODES = ("mseq", "masked")








def detector_of(point):
    """The point's :class:`~fliss.sim.scene.detector.Detector`: its ``sensor_preset`` with the
    settings it gives (:func:`fliss.sim.scene.detector_options.detector_from`, the table of
    ``fliss board`` and the interference study); raises
    :exc:`~fliss.sim.scene.detector_options.DetectorSettingError` (a :exc:`ValueError`) naming
    the setting as written."""
    settings = {setting.name: point.get(setting.name) for setting in _DETECTOR_SETTINGS}
    detector = detector_from(point.get("sensor_preset"), settings, style="key")
    if point.get("spads", 1) == 1:
        for name in ("crosstalk", "crosstalk_diagonal"):
            if settings[name] is not None:
                raise DetectorSettingError(f"{name} = {settings[name]!r}: does nothing with "
                                           f"one SPAD (spads = 1)")
    return detector


def _check_scheme(full):
    """The checks that tie parameters of one scheme together."""
    scheme = full["scheme"]
    if scheme == "fliss":
        settings = _scheduler.Settings(mode=_delay.parse_mode(full["delay_mode"]),
                                       length=full["length"], mask_width=full["mask_width"],
                                       period=full["period_cycles"])
        try:
            settings.check()
        except ValueError as error:
            raise ValueError(f"FLISS settings of the point: {error}") from None
    if scheme == "code":
        golomb_code(np.random.default_rng(0), full["code_chips"], full["code_slots"])
        if window_codes(full) > full["period_cycles"] * LSB_PER_CYCLE:
            raise ValueError(f"The code's window ({window_codes(full)} TDC codes) must fit in "
                             f"a period of {full['period_cycles']} cycles")
    if (scheme == "code" or full["multi_hit"]) and full["keep"] != "last":
        raise ValueError(f"Point parameter keep ({full['keep']!r}) chooses the event of a "
                         f"single-hit TDC: the TDC of this point keeps every event")
    if full["coincidence"] > full["spads"]:
        raise ValueError(f"Point parameter coincidence ({full['coincidence']}) must be at most "
                         f"spads ({full['spads']})")
    dead_ns = detector_of(full).dead_time_s * 1e9
    if full["coincidence"] > 1 and full["coincidence_window_ns"] > dead_ns:
        raise ValueError(f"Point parameter coincidence_window_ns must be at most the dead time "
                         f"({dead_ns:g} ns), not {full['coincidence_window_ns']!r}")


def check_point(point):
    """The point with defaults filled in and every value checked; raises :exc:`ValueError` with
    one line for an unknown name or a bad value."""
    full = filled(point, PARAMETERS)
    _choice(full, "scheme", EMISSIONS)
    _choice(full, "delay_mode", _DELAY_MODES)
    _choice(full, "keep", ("last", "first"))
    if not isinstance(full["multi_hit"], (bool, np.bool_)):
        raise ValueError(f"Point parameter multi_hit must be true or false, "
                         f"not {full['multi_hit']!r}")
    for name, low, high in (("length", 2, 32), ("mask_width", 1, 16),
                            ("period_cycles", 2, 1 << 20), ("hop_periods", 1, 1024),
                            ("hop_step_cycles", 1, 1024), ("hop_dwell", 1, 1 << 24),
                            ("code_chips", 1, 16), ("code_slots", 1, 256),
                            ("code_slot_cycles", 1, 64), ("spads", 1, 64),
                            ("coincidence", 1, 64), ("cameras", 1, 64),
                            ("frames", 1, 1 << 24)):
        full[name] = _integer(full, name, low, high)
    full["coincidence_window_ns"] = _real(full, "coincidence_window_ns", 0.0, 1e3,
                                          open_low=True)
    full["aggressor_power"] = _real(full, "aggressor_power", 0.0)
    full["ppm_spread"] = _real(full, "ppm_spread", 0.0, 1e5)
    full["t_int_s"] = _real(full, "t_int_s", 0.0, 1.0, open_low=True)
    full["detections_per_frame"] = _real(full, "detections_per_frame", 0.0)
    full["background_hz"] = _real(full, "background_hz", 0.0, 1e10)
    full["threshold_sigma"] = _real(full, "threshold_sigma", 0.0, open_low=True)
    window_m = TDC_CODES * TDC_LSB_S * SPEED_OF_LIGHT / 2
    full["distance_m"] = _real(full, "distance_m", 0.0, window_m * 0.9)
    _check_scheme(full)
    return full


def pulses_per_frame(point):
    """The victim's mean laser pulses in a frame (chips for ``code``)."""
    chips = point["code_chips"] if point["scheme"] == "code" else 1
    return point["t_int_s"] * DEFAULT_CLOCK_HZ / mean_period_cycles(point) * chips




def evaluate(point, seed):
    """One sweep point: the decision metrics of ``point`` over ``frames`` independent frames
    (each with its own draw of the cameras), from ``seed`` (a ``numpy.random.SeedSequence``;
    the same seed gives the same result). A flat dict (see :mod:`fliss.sim.studies.schemes`)."""
    if not isinstance(seed, np.random.SeedSequence):
        raise ValueError(f"The seed must be a numpy.random.SeedSequence, not {seed!r}")
    point = check_point(point)
    detector = detector_of(point)
    pulses = pulses_per_frame(point)
    tof_s = time_of_flight(point["distance_m"])
    inner = dict(point, _tof_lsb=tof_s / TDC_LSB_S,
                 _detections_per_pulse=point["detections_per_frame"] / pulses)
    fwhm_s = math.hypot(FWHM_S, detector.jitter_fwhm_s)
    frames = point["frames"]
    judged, errors, windows = [], [], 0
    counts = events = None
    for index in range(frames):
        rng = np.random.default_rng(np.random.SeedSequence(
            seed.entropy, spawn_key=tuple(seed.spawn_key) + (index,)))
        frame = simulate_frame(inner, detector, rng)
        windows += frame.windows
        counts = frame.counts if counts is None else counts + frame.counts
        events = frame.events if events is None else events + frame.events
        verdict = classify(frame.histogram, tof_s, fwhm_s,
                           threshold_sigma=point["threshold_sigma"])
        judged.append(verdict)
        if not verdict.miss:
            errors.append(verdict.depth_error_m)
    result = {"frames": frames}
    _proportion(result, "miss", sum(frame.miss for frame in judged), frames)
    _proportion(result, "ghost", sum(frame.ghost for frame in judged), frames)
    _proportion(result, "wrong_depth", sum(frame.wrong_depth for frame in judged), frames)
    _proportion(result, "failure", sum(frame.wrong_depth or frame.miss for frame in judged),
                frames)
    errors = np.asarray(errors)
    result["depth_error_mean_m"] = float(errors.mean()) if len(errors) else None
    result["depth_error_rms_m"] = float(np.sqrt(np.mean(errors ** 2))) if len(errors) else None
    target = np.mean([frame.target_height for frame in judged])
    other = np.mean([frame.other_height for frame in judged])
    result["s_db"] = 10 * math.log10(target / other) if target > 0 and other > 0 else None
    result["pulses_per_frame"] = float(pulses)
    result["detections_per_pulse"] = float(inner["_detections_per_pulse"])
    result["windows_per_frame"] = windows / frames
    aggressors = slice(2, 2 + point["cameras"] - 1)
    result["echo_counts_per_frame"] = float(counts[0] / frames)
    result["echo_events_per_frame"] = float(events[0] / frames)
    result["background_events_per_frame"] = float(events[1] / frames)
    result["aggressor_events_per_frame"] = float(events[aggressors].sum() / frames)
    result["effect_events_per_frame"] = float(events[2 + point["cameras"] - 1:].sum() / frames)
    return result
