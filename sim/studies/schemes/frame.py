"""One frame of a scheme: the cameras' photons at the victim's macro-pixel, its SPADs, its
coincidence gate, its TDC and its histogram (see :mod:`fliss.sim.studies.schemes`)."""

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ....hdl.event import TDC_LSB_S
from ...scene.description import FWHM_PER_SIGMA, TDC_CODES
from .emitters import Camera, LSB_PER_CYCLE
from .macropixel import avalanches, coincidences, correlate, tdc


__all__ = ["FWHM_S", "Frame", "simulate_frame", "window_codes"]

#: FWHM of every camera's laser pulse, as the interference study's (2.1 ns).
FWHM_S = 2.1e-9

_ECHO, _BACKGROUND = 0, 1


@dataclass
class Frame:
    """What one frame gave: the histogram the detector judges (for ``code``, the correlation
    of the TDC's histogram with the victim's code), the victim's windows, the SPADs' counts
    and the TDC's events of each source (0: echo, 1: background and dark counts, then each
    aggressor, then afterpulses and crosstalk)."""

    histogram: np.ndarray
    windows: int
    counts: np.ndarray
    events: np.ndarray


def window_codes(point):
    """TDC codes of one window: 8192, and for ``code`` the longest chip offset more (the
    correlation then gives 8192 codes)."""
    if point["scheme"] != "code":
        return TDC_CODES
    span = (point["code_slots"] - 1) * point["code_slot_cycles"] * LSB_PER_CYCLE
    return TDC_CODES + int(math.ceil(span))


def _pulsed(rng, emissions, mean, shift, sigma):
    """Photons of a pulsed source: a Poisson number per pulse of mean ``mean`` (drawn as one
    Poisson total over the pulses, each photon on a uniform pulse: the same law), each at its
    pulse's emission plus ``shift`` plus a Gaussian of ``sigma``."""
    if not len(emissions) or mean <= 0:
        return np.zeros(0)
    count = int(rng.poisson(mean * len(emissions)))
    index = rng.integers(0, len(emissions), count)
    return emissions[index] + shift + sigma * rng.standard_normal(count)


def _background(rng, rate_hz, start, end):
    """A Poisson process of ``rate_hz`` from ``start`` to ``end``, in time order (the order
    statistics of uniforms: cumulative sums of exponentials, scaled)."""
    count = int(rng.poisson(rate_hz * (end - start) * TDC_LSB_S))
    if not count:
        return np.zeros(0)
    gaps = np.cumsum(rng.standard_exponential(count + 1))
    return start + (end - start) * (gaps[:-1] / gaps[-1])


@lru_cache(maxsize=16)
def _dark_rates(detector, n):
    """The SPADs' dark count rates (a property of the sensor, the same every frame)."""
    return tuple(float(rate) for rate in detector.dark_rates(n))


def _merge(ordered, times, sources, spads):
    """The photons ``times`` (any order, with their ``sources`` and ``spads``) merged into the
    sorted ``ordered = (times, sources, spads)``: the three arrays, in time order."""
    order = np.argsort(times, kind="stable")
    times, sources, spads = times[order], sources[order], spads[order]
    at = np.searchsorted(ordered[0], times, side="right") + np.arange(len(times))
    rest = np.ones(len(ordered[0]) + len(times), dtype=bool)
    rest[at] = False
    merged = []
    for old, new in zip(ordered, (times, sources, spads)):
        both = np.empty(len(rest), dtype=np.result_type(old, new))
        both[at] = new
        both[rest] = old
        merged.append(both)
    return tuple(merged)


def photons(point, detector, victim, aggressors, rng, frame_lsb, margin):
    """``(times, sources, spads)`` of every photon that reaches the macro-pixel in the frame
    (and ``margin`` LSBs before it, so that the SPADs' state at its start is drawn too), in
    time order; ``victim``: the emissions of the victim's pulses."""
    n = point["spads"]
    tof = point["_tof_lsb"]
    sigma = math.hypot(FWHM_S / FWHM_PER_SIGMA, detector.sigma_s) / TDC_LSB_S
    mean = point["_detections_per_pulse"] * detector.pdp
    start, end = -margin, frame_lsb + window_codes(point)
    # The ambient light, drawn in order (it is most of the photons at high rates)
    ambient = _background(rng, point["background_hz"] * detector.pdp, start, end)
    ordered = (ambient, np.full(len(ambient), _BACKGROUND, dtype=np.int16),
               rng.integers(0, n, len(ambient)))
    parts = [_pulsed(rng, victim, mean, tof, sigma), np.zeros(0)]
    for camera in aggressors:
        parts.append(_pulsed(rng, camera.pulses(start - tof, end), mean *
                             point["aggressor_power"], tof, sigma))
    sources = np.concatenate([np.full(len(part), index, dtype=np.int16)
                              for index, part in enumerate(parts)])
    spads = rng.integers(0, n, len(sources))
    times = [np.concatenate(parts)]
    if detector.dark_count_hz or detector.hot_dark_count_hz:
        for spad, rate in enumerate(_dark_rates(detector, n)):
            dark = _background(rng, rate, start, end)
            times.append(dark)
            sources = np.concatenate((sources, np.full(len(dark), _BACKGROUND, np.int16)))
            spads = np.concatenate((spads, np.full(len(dark), spad)))
    return _merge(ordered, np.concatenate(times), sources, spads)


def simulate_frame(point, detector, rng):
    """One frame of a checked point (see :func:`fliss.sim.studies.schemes.check_point`), its
    cameras and photons drawn from ``rng``: a :class:`Frame`."""
    victim = Camera.draw(point, rng, victim=True)
    aggressors = [Camera.draw(point, rng) for _ in range(point["cameras"] - 1)]
    frame_lsb = point["t_int_s"] / TDC_LSB_S
    length = window_codes(point)
    margin = 2.0 * length + detector.dead_time_s / TDC_LSB_S
    starts = victim.bursts(0.0, frame_lsb)
    emissions = (starts[:, None] + victim.chip_offsets_lsb[None, :]).ravel()
    times, sources, spads = photons(point, detector, emissions, aggressors, rng, frame_lsb,
                                    margin)
    first_child = 2 + len(aggressors)
    counted, source = avalanches(times, sources, spads, detector, point["spads"], rng,
                                 first_child)
    gate = coincidences(counted, point["coincidence"], point["coincidence_window_ns"] * 1e-9 /
                        TDC_LSB_S)
    fired, fired_source = counted[gate], source[gate]
    index, offset = tdc(fired, starts, length, keep=point["keep"],
                        multi=point["scheme"] == "code" or point["multi_hit"])
    raw = np.bincount(np.minimum(offset.astype(np.int64), length - 1), minlength=length)
    if point["scheme"] == "code":
        chips = np.rint(victim.chip_offsets_lsb).astype(np.int64)
        histogram = correlate(raw, chips, TDC_CODES)
    else:
        histogram = raw
    sources_count = first_child + 2
    counts = np.bincount(source.astype(np.int64), minlength=sources_count)
    events = np.bincount(fired_source[index].astype(np.int64), minlength=sources_count)
    return Frame(histogram=histogram, windows=len(starts), counts=counts, events=events)
