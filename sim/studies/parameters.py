"""A sweep point's parameters checked one by one: an integer or a real number within its
limits, or one line naming the parameter (the studies' ``evaluate`` functions read their points
through these)."""

import math

import numpy as np


__all__ = ["filled", "choice", "integer", "real"]


def filled(point, defaults):
    """``point`` (a dict of parameters) over ``defaults`` (every parameter's default, by name);
    :exc:`ValueError` for a point that is not a dict or names a parameter not in ``defaults``."""
    if not isinstance(point, dict):
        raise ValueError(f"A sweep point must be a dict of parameters, not {point!r}")
    unknown = sorted(set(point) - set(defaults))
    if unknown:
        raise ValueError(f"Unknown point parameter {unknown[0]!r}; known: "
                         f"{', '.join(defaults)}")
    return dict(defaults, **point)


def choice(point, name, choices):
    """``point[name]``, one of ``choices``; :exc:`ValueError` otherwise."""
    value = point[name]
    if value not in choices:
        raise ValueError(f"Point parameter {name} must be one of {', '.join(map(str, choices))}, "
                         f"not {value!r}")
    return value


def integer(point, name, low, high):
    """``point[name]``, an integer from ``low`` to ``high``; :exc:`ValueError` otherwise."""
    value = point[name]
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
            or not low <= value <= high:
        raise ValueError(f"Point parameter {name} must be an integer from {low} to {high}, "
                         f"not {value!r}")
    return int(value)


def real(point, name, low, high=math.inf, *, open_low=False):
    """``point[name]``, a finite number from ``low`` (above it, ``open_low``) to ``high``;
    :exc:`ValueError` otherwise."""
    value = point[name]
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or not low <= value <= high \
            or (open_low and value == low):
        side = ">" if open_low else ">="
        bound = "" if high == math.inf else f" and <= {high:g}"
        raise ValueError(f"Point parameter {name} must be a finite number {side} {low:g}{bound}, "
                         f"not {value!r}")
    return float(value)
