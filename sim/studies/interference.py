"""One point of the interference study: how often a frame reports a wrong distance.

:func:`evaluate` runs the photon-level scene simulator (:mod:`fliss.sim.scene`: the gateware's
delay sequences, Poisson photons, SPAD dead time, the single-hit last-photon TDC, so pile-up and
overwriting by the aggressors' photons are in) for ``frames`` acquisitions of ``t_int_s`` each,
judges every histogram with the detector of :mod:`fliss.sim.studies.detection`, and returns the decision
metrics as a flat dict of scalars, one row of a sweep.

The photon-level simulator is fast enough for this (``benchmarks/scene_throughput.py``: about
1e7 laser cycles per second, 1 to 3 ms for a 10 ms frame at the default 1 MHz PRF), so no
approximate frame model stands between the sweep and the physics.

Runs
----
The frames come in runs of ``frames_per_run`` consecutive acquisitions. Each run draws, from the
point's seed, every aggressor's oscillator (a frequency offset uniform in ``±ppm_spread`` ppm from
the victim's clock), its phase (a start uniform over one victim period), its own FLISS seed, and,
with ``victim_seed = 0``, the victim's seed. Within a run the aggressors drift as their offsets
make them; runs are independent. The confidence intervals treat frames as independent: with
``frames_per_run > 1`` frames of one run are correlated and the true intervals are wider.

Point parameters (:data:`PARAMETERS`, defaults in brackets)
-----------------------------------------------------------
scheme ["mseq"]
    The victim's delay source, a delay mode (:data:`SCHEMES`, those of
    :data:`~fliss.hdl.delay.modes.MODES`): ``"off"``, ``"mseq"``, ``"masked"`` or ``"keyed"``
    (Trivium, :mod:`fliss.sim.models.trivium`: ``Wm``-bit delays from the keystream of an 80-bit
    key drawn per run from the point's seed, or ``victim_seed`` if not 0, and IV 0).
grid [False]
    Grid scheduler (pulse ``k`` fires ``R[k]`` after ``k T``) instead of interval mode.
length [6], mask_width [6]
    ``L`` of ``mseq`` and ``Wm`` of ``masked`` and ``keyed``.
period_cycles [80]
    The victim's period ``T`` in clock cycles (80: 1 MHz at 80 MHz).
victim_seed [0]
    The victim's delay seed (the key of ``keyed``); 0 draws one per run.
fine_step [1]
    Modelled sub-cycle delay steps: the victim's delays in steps of one cycle / 1, 2, 4, 8 or 16
    (:attr:`fliss.sim.scene.Scene.fine_step`).
aggressors [1]
    Number of aggressors, 0 to 64.
aggressor_power [1.0]
    Detections per pulse of each aggressor at the victim's pixel, relative to the victim's echo.
aggressor_kind ["free"]
    ``"free"``: free-running with FLISS off at the victim's nominal period on its own
    oscillator. ``"fliss"``: the same, running the victim's scheme (mode, L, Wm, grid) with its
    own random seed. ``"locked"``: the paper's worst case, FLISS off, locked to the victim's clock
    (no ppm) at the victim's effective PRF (``T + E(R) / fine_step`` cycles, ``T`` in grid mode).
    ``"predicting"``: the attacker of :mod:`fliss.sim.studies.attacker` (see
    :mod:`fliss.sim.studies.predicting_aggressor`): it watches the victim's laser, fires at the measured
    effective PRF until it predicts the victim's delays, then so that its pulse arrives the time
    of flight of ``ghost_m`` after each TDC start. One attack per run serves all of them (they
    see the same victim), so they fire together; their unlocked train starts ``offset_ns``
    late (drawn per run, uniform over one victim period, if negative), in whole cycles. Not
    with ``fine_step`` > 1 (the attacker reads whole clock cycles).
ghost_m [10.0]
    Distance of the ghost a locked predicting aggressor injects.
ppm_spread [50.0]
    Half-width in ppm of the uniform spread of the aggressors' frequency offsets (not for
    ``locked`` and ``predicting``).
jitter_ps [0.0]
    RMS phase jitter of each aggressor pulse, ps.
offset_ns [-1.0]
    Start of every aggressor after the victim's first edge, ns; negative: drawn per aggressor and
    run, uniform over one victim period (``predicting``: the delay of the unlocked train).
t_int_s [0.01]
    Integration time of a frame.
threshold_sigma [5.0]
    Detection threshold in noise deviations of the smoothed histogram (at least one count per
    code: :func:`fliss.analysis.peaks.threshold_height`).
frames [1000], frames_per_run [1]
    Frames of the point, and consecutive frames per run (more per run is cheaper, fewer
    independent draws of the aggressors).
distance_m [4.0], detections_per_pulse [0.05], background_hz [1e5]
    Target distance, the victim's echo in detections per pulse, ambient rate at the pixel
    (photons a ready SPAD would detect with a PDP of 1: the detector's ``pdp`` thins them).
sensor_preset, pdp, dark_count, hot_pixels, hot_dark_count, dead_time, paralysable, jitter,
jitter_tail, jitter_tail_share, afterpulsing, afterpulse_tau, afterpulse_weights [not given]
    The victim's detector (:class:`~fliss.sim.scene.detector.Detector`), by the names of
    ``fliss board``'s options and with the same values as text with units (``dead_time =
    "22ns"``, ``afterpulsing = "1.4%"``, ``paralysable = true``;
    :mod:`fliss.sim.scene.detector_options`): a preset, each setting given replacing its
    value; none given: the model's default detector (20 ns non-paralysable, 100 ps jitter).
    One pixel: no crosstalk.

Results
-------
``frames``, ``runs``, ``miss``, ``ghost``, ``wrong_depth`` (counts of frames); ``p_miss``,
``p_ghost``, ``p_wrong_depth`` with 95 % Wilson bounds ``*_lo`` and ``*_hi``;
``depth_error_mean_m`` and ``depth_error_rms_m`` over the frames that detect the target (``None``
if none does); ``s_db``: 10 log10 of the mean height of the target's peak over the mean height of
the highest point outside the target's window (both above the background, whether detected or
not); ``signal_recorded``: fraction of the victim's detected photons the TDC kept (pile-up and
overwriting lower it); ``aggressor_counts_per_frame``: the aggressors' recorded photons per
frame; ``background_counts_per_frame``: the recorded photons of ambient light and dark counts
per frame; ``attack_locked_runs``: runs in which the predicting attacker locked, and
``attack_locked_after_mean``: its mean observed pulses until the first lock over those runs
(``None`` for other kinds, or without a lock); and the detection curve as three JSON lists of equal length: ``curve_threshold`` (noise
deviations), ``curve_p_detect`` and ``curve_false_per_frame``.
"""

import json
import math

import numpy as np

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.delay.modes import MODES, SIZES
from ...hdl.delay.settings import KEY_BITS, MAX_LENGTH
from ...hdl.event import TDC_LSB_S
from ..models import delay as _delay
from ..models import scheduler as _scheduler
from .detection import classify, detection_curve, proportion as _proportion
from .parameters import choice as _choice, filled, integer as _integer, real as _real
from .predicting_aggressor import attack_edges
from ..scene.acquisition import acquire
from ..scene.detector_options import SETTINGS as _DETECTOR_SETTINGS, detector_from
from ..scene.description import (COUNTERS, FINE_STEPS, SPEED_OF_LIGHT, TDC_CODES, Aggressor, Scene,
                                 time_of_flight)


__all__ = ["PARAMETERS", "SCHEMES", "KINDS", "CURVE_THRESHOLDS", "check_point", "scene_of",
           "evaluate"]


#: Every point parameter with its default (see the module's documentation).
PARAMETERS = {
    "scheme": "mseq",
    "grid": False,
    "length": 6,
    "mask_width": 6,
    "period_cycles": 80,
    "victim_seed": 0,
    "fine_step": 1,
    "aggressors": 1,
    "aggressor_power": 1.0,
    "aggressor_kind": "free",
    "ghost_m": 10.0,
    "ppm_spread": 50.0,
    "jitter_ps": 0.0,
    "offset_ns": -1.0,
    "t_int_s": 0.01,
    "threshold_sigma": 5.0,
    "frames": 1000,
    "frames_per_run": 1,
    "distance_m": 4.0,
    "detections_per_pulse": 0.05,
    "background_hz": 1e5,
    # The detector, by the names of fliss board's options (None: not given)
    "sensor_preset": None,
    **{setting.name: None for setting in _DETECTOR_SETTINGS
       if not setting.name.startswith("crosstalk")},
}

#: Victim delay sources: the delay modes (:data:`~fliss.hdl.delay.modes.MODES`).
SCHEMES = tuple(row.name for row in MODES.values())

#: Aggressor kinds.
KINDS = ("free", "fliss", "locked", "predicting")

#: Thresholds of the detection curve, noise deviations of the smoothed histogram.
CURVE_THRESHOLDS = tuple(float(x) for x in np.round(np.geomspace(3.0, 3000.0, 16), 2))

_MAX_AGGRESSORS = 64
_FWHM_S = 2.1e-9








def check_point(point):
    """The point with defaults filled in and every value checked; raises :exc:`ValueError` with
    one line for an unknown name or a bad value."""
    full = filled(point, PARAMETERS)
    _choice(full, "scheme", SCHEMES)
    _choice(full, "aggressor_kind", KINDS)
    if not isinstance(full["grid"], (bool, np.bool_)):
        raise ValueError(f"Point parameter grid must be true or false, not {full['grid']!r}")
    for name, size in SIZES.items():            # length, mask_width
        full[name] = _integer(full, name, size.minimum, size.maximum)
    full["period_cycles"] = _integer(full, "period_cycles", 2, 1 << 20)
    full["victim_seed"] = _integer(full, "victim_seed", 0, (1 << 32) - 1)
    _choice(full, "fine_step", FINE_STEPS)
    full["aggressors"] = _integer(full, "aggressors", 0, _MAX_AGGRESSORS)
    for name in ("aggressor_power", "ppm_spread", "jitter_ps", "detections_per_pulse",
                 "background_hz"):
        full[name] = _real(full, name, 0.0)
    full["ppm_spread"] = _real(full, "ppm_spread", 0.0, 1000.0)
    full["offset_ns"] = _real(full, "offset_ns", -math.inf)
    full["t_int_s"] = _real(full, "t_int_s", 0.0, 10.0, open_low=True)
    full["threshold_sigma"] = _real(full, "threshold_sigma", 0.0, open_low=True)
    full["frames"] = _integer(full, "frames", 1, 1 << 24)
    full["frames_per_run"] = _integer(full, "frames_per_run", 1, 1 << 24)
    window_m = TDC_CODES * TDC_LSB_S * SPEED_OF_LIGHT / 2
    full["distance_m"] = _real(full, "distance_m", 0.0, window_m * 0.9)
    full["ghost_m"] = _real(full, "ghost_m", 0.0, window_m * 0.9)
    if full["aggressor_kind"] == "predicting" and full["fine_step"] != 1:
        raise ValueError(f"The predicting aggressor reads whole clock cycles: it needs "
                         f"fine_step 1, not {full['fine_step']!r}")
    # The victim's settings must hold together (seed range, grid room for the delays)
    _victim(full, 1)
    _detector(full)
    return full


def _detector(point):
    """The point's :class:`~fliss.sim.scene.detector.Detector`."""
    return detector_from(point["sensor_preset"],
                         {setting.name: point[setting.name] for setting in _DETECTOR_SETTINGS
                          if setting.name in point}, style="key")


def _row(point):
    # The row of the point's scheme in the table of delay modes
    return MODES[_delay.parse_mode(point["scheme"])]


def _keyed(point):
    return _row(point).keyed


def _seed_fields(point, seed):
    # The drawn seed as the delay source takes it: keyed, the key (with seed 1 and IV 0)
    return dict(seed=1, key=seed) if _keyed(point) else dict(seed=seed, key=0)


def _victim(point, seed):
    settings = _scheduler.Settings(mode=_delay.parse_mode(point["scheme"]), length=point["length"],
                                   mask_width=point["mask_width"], iv=0,
                                   **_seed_fields(point, seed),
                                   period=point["period_cycles"], grid=bool(point["grid"]))
    try:
        return settings.check()
    except ValueError as error:
        raise ValueError(f"Victim settings of the point: {error}") from None


def _seed_bits(point):
    # The bits of a drawn seed: the key's, those of the setting that sizes the seed's register,
    # or the seed register's 32
    row = _row(point)
    if row.keyed:
        return KEY_BITS
    return point[row.seed_bits] if isinstance(row.seed_bits, str) else MAX_LENGTH


def _draw_seed(rng, bits):
    """A non-zero seed (key) of ``bits`` bits."""
    if bits <= 32:
        return int(rng.integers(1, 1 << bits))
    while True:
        value = int.from_bytes(rng.bytes((bits + 7) // 8), "little") & ((1 << bits) - 1)
        if value:
            return value


def _effective_period(point):
    """The victim's mean period in clock cycles (its effective PRF's inverse)."""
    if point["grid"]:
        return float(point["period_cycles"])
    mean = _delay.mean_delay(point["scheme"], length=point["length"],
                             mask_width=point["mask_width"])
    return point["period_cycles"] + float(mean) / point["fine_step"]


def scene_of(point, rng):
    """The scene of one run of a checked point, its random choices drawn from ``rng``."""
    bits = _seed_bits(point)
    victim = _victim(point, point["victim_seed"] or _draw_seed(rng, bits))
    period_s = point["period_cycles"] / DEFAULT_CLOCK_HZ
    kind = point["aggressor_kind"]
    aggressors = []
    for _ in range(point["aggressors"]):
        offset = point["offset_ns"] * 1e-9 if point["offset_ns"] >= 0 else \
            float(rng.uniform(0.0, period_s))
        ppm = 0.0 if kind in ("locked", "predicting") else \
            float(rng.uniform(-1.0, 1.0) * point["ppm_spread"])
        seed = _draw_seed(rng, bits)
        common = dict(offset_s=offset, ppm=ppm, jitter_s=point["jitter_ps"] * 1e-12,
                      detections_per_pulse=point["detections_per_pulse"] *
                      point["aggressor_power"], fwhm_s=_FWHM_S)
        if kind == "locked":
            aggressors.append(Aggressor(period_cycles=_effective_period(point), **common))
        elif kind == "predicting":
            # Fired on the attack's triggers: its pulse arrives the ghost's time of flight after
            common.update(offset_s=0.0)
            aggressors.append(Aggressor(period_cycles=point["period_cycles"],
                                        tof_s=time_of_flight(point["ghost_m"]), **common))
        elif kind == "free" or point["scheme"] == "off":
            aggressors.append(Aggressor(period_cycles=point["period_cycles"], **common))
        else:
            aggressors.append(Aggressor(period_cycles=point["period_cycles"],
                                        mode=point["scheme"], length=point["length"],
                                        mask_width=point["mask_width"],
                                        **_seed_fields(point, seed),
                                        grid=bool(point["grid"]), **common))
    return Scene(victim=victim, distance_m=point["distance_m"],
                 detections_per_pulse=point["detections_per_pulse"], fwhm_s=_FWHM_S,
                 aggressors=tuple(aggressors), background_hz=point["background_hz"],
                 fine_step=point["fine_step"], detector=_detector(point))


def _child(seed, *key):
    return np.random.SeedSequence(seed.entropy, spawn_key=tuple(seed.spawn_key) + key)




def evaluate(point, seed):
    """One sweep point: the decision metrics of ``point`` (see the module's documentation).

    Parameters
    ----------
    point : dict
        Parameter names of :data:`PARAMETERS`; missing ones take the defaults.
    seed : numpy.random.SeedSequence
        All randomness comes from it (it is not spawned from, so it may be reused: the same seed
        gives the same result).

    Returns
    -------
    dict
        Flat dict of scalars (see the module's documentation).
    """
    if not isinstance(seed, np.random.SeedSequence):
        raise ValueError(f"The seed must be a numpy.random.SeedSequence, not {seed!r}")
    point = check_point(point)
    frames, per_run = point["frames"], point["frames_per_run"]
    tof_s = time_of_flight(point["distance_m"])
    fwhm_s = math.hypot(_FWHM_S, _detector(point).jitter_fwhm_s)
    floor = min(CURVE_THRESHOLDS[0], point["threshold_sigma"])
    judged, errors = [], []
    counts = np.zeros((1 + point["aggressors"], len(COUNTERS)), dtype=np.int64)
    background = 0
    runs = -(-frames // per_run)
    predicting = point["aggressor_kind"] == "predicting" and point["aggressors"] > 0
    locked_after = []
    for run in range(runs):
        rng = np.random.default_rng(_child(seed, run, 0))
        scene = scene_of(point, rng)
        number = min(per_run, frames - run * per_run)
        edges = None
        if predicting:
            end = number * int(round(point["t_int_s"] * DEFAULT_CLOCK_HZ))
            period = point["period_cycles"]
            phase = int(round(point["offset_ns"] * 1e-9 * DEFAULT_CLOCK_HZ)) \
                if point["offset_ns"] >= 0 else int(rng.integers(0, period))
            triggers, after = attack_edges(scene.victim, end, phase_cycles=phase,
                                           seed=_child(seed, run, 2))
            edges = [triggers] * point["aggressors"]
            if after is not None:
                locked_after.append(after)
        acquisitions = acquire(scene, point["t_int_s"], number, seed=_child(seed, run, 1),
                               chunk_cycles=1 << 14, aggressor_edges=edges)
        source_counts = acquisitions.counts.sum(axis=0)
        counts[0] += source_counts[0]
        counts[1:] += source_counts[2:2 + point["aggressors"]]     # (not the afterpulses)
        background += int(source_counts[1, COUNTERS.index("recorded")])
        for histogram in acquisitions.histograms:
            frame = classify(histogram, tof_s, fwhm_s, threshold_sigma=point["threshold_sigma"],
                             floor_sigma=floor)
            judged.append(frame)
            if not frame.miss:
                errors.append(frame.depth_error_m)
    result = {"frames": frames, "runs": runs}
    _proportion(result, "miss", sum(frame.miss for frame in judged), frames)
    _proportion(result, "ghost", sum(frame.ghost for frame in judged), frames)
    _proportion(result, "wrong_depth", sum(frame.wrong_depth for frame in judged), frames)
    errors = np.asarray(errors)
    result["depth_error_mean_m"] = float(errors.mean()) if len(errors) else None
    result["depth_error_rms_m"] = float(np.sqrt(np.mean(errors ** 2))) if len(errors) else None
    target = np.mean([frame.target_height for frame in judged])
    other = np.mean([frame.other_height for frame in judged])
    result["s_db"] = 10 * math.log10(target / other) if target > 0 and other > 0 else None
    recorded = COUNTERS.index("recorded")
    detected = counts[0, COUNTERS.index("generated")] - counts[0, COUNTERS.index("outside")] - \
        counts[0, COUNTERS.index("dead")]
    result["signal_recorded"] = float(counts[0, recorded] / detected) if detected else None
    result["aggressor_counts_per_frame"] = float(counts[1:, recorded].sum() / frames)
    result["background_counts_per_frame"] = background / frames
    result["attack_locked_runs"] = len(locked_after) if predicting else None
    result["attack_locked_after_mean"] = float(np.mean(locked_after)) if locked_after else None
    detect, false = detection_curve(judged, CURVE_THRESHOLDS)
    result["curve_threshold"] = json.dumps(list(CURVE_THRESHOLDS))
    result["curve_p_detect"] = json.dumps([round(float(x), 6) for x in detect])
    result["curve_false_per_frame"] = json.dumps([round(float(x), 6) for x in false])
    return result
