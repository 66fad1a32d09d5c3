"""Distance from a peak's position: time of flight and depth (the speed of light, written once)."""

import numpy as np


__all__ = ["C_M_S", "tof_s", "depth_m"]

#: Speed of light, m/s.
C_M_S = 299_792_458.0


def tof_s(position_bins, bin_s: float) -> np.ndarray:
    """Time of flight in seconds of a peak at ``position_bins`` (bins, fractional, from the
    start of bin 0, as DEPTH packets give it: bin ``j`` spans ``j … j + 1``; NaN stays NaN)
    with bins of ``bin_s`` seconds."""
    return np.asarray(position_bins, dtype=float) * bin_s


def depth_m(time_of_flight_s) -> np.ndarray:
    """Distance in metres of a target whose echo takes ``time_of_flight_s`` (there and back)."""
    return np.asarray(time_of_flight_s, dtype=float) * C_M_S / 2
