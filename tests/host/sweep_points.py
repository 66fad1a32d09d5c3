"""Cheap point functions for the sweep tests: deterministic given the seed, instant or slow."""

import json
import time

import numpy as np


PARAMETERS = {"scheme": "off", "aggressors": 1, "t_int_s": 0.01, "frames": 100,
              "aggressor_power_db": 0.0, "sleep_s": 0.0}


def check_point(point):
    """Refuses what :func:`evaluate` refuses, before any work."""
    unknown = sorted(set(point) - set(PARAMETERS))
    if unknown:
        raise ValueError(f"unknown parameter {unknown[0]!r}")
    if {**PARAMETERS, **point}["frames"] < 1:
        raise ValueError(f"frames must be at least 1, not {point['frames']}")


def evaluate(point, seed):
    """Draws from the point's seed; metrics computed from the parameters and the draws."""
    unknown = sorted(set(point) - set(PARAMETERS))
    if unknown:
        raise ValueError(f"unknown parameter {unknown[0]!r}")
    p = {**PARAMETERS, **point}
    if p["frames"] < 1:
        raise ValueError(f"frames must be at least 1, not {p['frames']}")
    time.sleep(p["sleep_s"])
    draws = np.random.default_rng(seed).random(p["frames"])
    wrong = int(np.count_nonzero(draws < 0.05 * p["aggressors"]))
    return {"frames": p["frames"], "wrong_depth": wrong,
            "p_wrong_depth": wrong / p["frames"],
            "p_wrong_depth_lo": max(wrong / p["frames"] - 0.1, 0.0),
            "p_wrong_depth_hi": min(wrong / p["frames"] + 0.1, 1.0),
            "s_db": 30.0 - p["aggressor_power_db"], "first_draw": float(draws[0]),
            "scheme_seen": p["scheme"], "nothing": None,
            "curve_p_detect": json.dumps([1.0, 0.9, 0.5]),
            "curve_false_per_frame": json.dumps([2.0, 0.1, 0.0])}
