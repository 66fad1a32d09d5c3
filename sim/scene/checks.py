"""Checks of the numbers that describe a scene, each refused with one clear line."""

import math

import numpy as np


__all__ = ["check_number"]


def check_number(value, what, *, positive=False):
    """Raise ``ValueError`` unless ``value`` is a finite number, ``>= 0`` (``> 0`` with
    ``positive``); ``what`` names it in the message."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value < 0 or (positive and value == 0):
        kind = "positive" if positive else "non-negative"
        raise ValueError(f"{what} must be a finite {kind} number, not {value!r}")
