"""The detector of the scene simulator: one description of the SPAD pixels' physics.

:class:`Detector` holds what a pixel's SPAD does to the photons that reach it, the same for
every pixel of an array but its dark count rate:

* **photon detection probability** ``pdp``: each photon of the scene (echo, aggressors,
  ambient light) is detected with this probability (a Poisson stream thinned: its mean times
  ``pdp``). 1 (the default): the scene's rates are detections already, as before.
* **dark counts**: each pixel adds its own Poisson stream of dark counts (not thinned by the
  PDP) to the scene's ``background_hz`` (counted with it, as ``background``). A pixel's rate
  is ``dark_count_hz * exp(dark_spread * z)`` (``z`` standard normal: log-normal across
  pixels, median ``dark_count_hz``), or, for a *hot* pixel (each pixel hot with probability
  ``hot_fraction``), ``hot_dark_count_hz * exp(dark_spread * z)``. The pixels' rates are a
  property of the sensor: drawn once from ``dark_seed``, pixel after pixel (pixel 0 of an
  array has the rate of the single pixel).
* **dead time** ``dead_time_s``, non-paralysable (the default: an avalanche leaves the SPAD
  blind for the dead time, a photon arriving then is lost and does nothing) or
  ``paralysable`` (every photon arriving, counted or not, starts an avalanche that restarts
  the dead time; it is counted only at least a dead time after the previous avalanche).
* **timing response**: a Gaussian jitter of FWHM ``jitter_fwhm_s`` (SPAD and TDC, added in
  quadrature to each pulse's width) and a diffusion tail: a share ``tail_fraction`` of the
  photons of the pulsed sources is late by an exponential delay of mean ``tail_s`` (photons
  absorbed below the junction diffuse to it).
* **afterpulsing**: every avalanche (counted or, paralysable, inside the dead time: visible
  or dead) releases a trapped carrier with probability ``afterpulse_probability``, after an
  exponential delay whose mean is one of ``afterpulse_s``, chosen with the probabilities
  ``afterpulse_weights`` (one or more exponentials). The carrier is an avalanche of its own
  if the SPAD is ready (non-paralysable; paralysable, it always is, counted or not) and can
  itself afterpulse: the expected afterpulses per photon avalanche form a geometric series.
* **optical crosstalk**: every avalanche of a pixel of an array fires each orthogonal
  neighbour with probability ``crosstalk_orthogonal`` and each diagonal one with
  ``crosstalk_diagonal`` (the layout is the array's: :attr:`PixelArray.columns
  <fliss.sim.scene.pixels.PixelArray.columns>`; a column's neighbours are the pixels above
  and below), later by a half-normal delay of the jitter's standard deviation: simultaneous
  within the jitter, never before its cause. The neighbour's avalanche is one like any other
  (dead time, afterpulses, crosstalk of its own).

The defaults are the simulator's behaviour before the detector was described: 20 ns
non-paralysable dead time, 100 ps FWHM jitter, nothing else.
"""

import math
from dataclasses import dataclass

import numpy as np

from .checks import check_number


__all__ = ["Detector"]


def _probability(value, what):
    check_number(value, what)
    if value > 1:
        raise ValueError(f"{what} must be a probability from 0 to 1, not {value!r}")


def _times(values, what):
    """``values`` as a tuple of finite positive numbers."""
    if isinstance(values, (int, float, np.integer, np.floating)) and \
            not isinstance(values, bool):
        values = (values,)
    if not isinstance(values, (tuple, list)):
        raise ValueError(f"{what} must be a tuple of numbers, not {values!r}")
    for value in values:
        check_number(value, what, positive=True)
    return tuple(float(value) for value in values)


@dataclass(frozen=True)
class Detector:
    """The SPAD pixels' physics (see :mod:`fliss.sim.scene.detector`); all times in seconds,
    rates in hertz, probabilities from 0 to 1."""

    pdp: float = 1.0
    dark_count_hz: float = 0.0
    dark_spread: float = 0.0
    hot_fraction: float = 0.0
    hot_dark_count_hz: float = 0.0
    dark_seed: int = 0
    dead_time_s: float = 20e-9
    paralysable: bool = False
    jitter_fwhm_s: float = 100e-12
    tail_fraction: float = 0.0
    tail_s: float = 0.0
    afterpulse_probability: float = 0.0
    afterpulse_s: tuple = ()
    afterpulse_weights: tuple = ()
    crosstalk_orthogonal: float = 0.0
    crosstalk_diagonal: float = 0.0

    def __post_init__(self):
        _probability(self.pdp, "Photon detection probability")
        if self.pdp == 0:
            raise ValueError("Photon detection probability must be above 0")
        check_number(self.dark_count_hz, "Dark count rate (Hz)")
        check_number(self.dark_spread, "Dark count spread (log-normal sigma)")
        _probability(self.hot_fraction, "Hot pixel fraction")
        check_number(self.hot_dark_count_hz, "Hot pixel dark count rate (Hz)")
        if isinstance(self.dark_seed, bool) or not isinstance(self.dark_seed, (int, np.integer)) \
                or self.dark_seed < 0:
            raise ValueError(f"Dark count seed must be a non-negative integer, "
                             f"not {self.dark_seed!r}")
        check_number(self.dead_time_s, "Dead time (s)")
        if not isinstance(self.paralysable, (bool, np.bool_)):
            raise ValueError(f"Paralysable must be True or False, not {self.paralysable!r}")
        check_number(self.jitter_fwhm_s, "Jitter FWHM (s)")
        _probability(self.tail_fraction, "Diffusion tail fraction")
        check_number(self.tail_s, "Diffusion tail time constant (s)")
        if self.tail_fraction > 0 and self.tail_s == 0:
            raise ValueError("A diffusion tail needs a positive time constant (tail_s)")
        _probability(self.afterpulse_probability, "Afterpulse probability")
        if self.afterpulse_probability == 1:
            raise ValueError("Afterpulse probability must be below 1 (each afterpulse can "
                             "afterpulse again)")
        times = _times(self.afterpulse_s, "Afterpulse time constants (s)")
        object.__setattr__(self, "afterpulse_s", times)
        weights = self.afterpulse_weights
        if isinstance(weights, (tuple, list)) and not weights and times:
            weights = (1.0,) * len(times)
        weights = tuple(float(w) for w in weights) if isinstance(weights, (tuple, list)) \
            else weights
        if not isinstance(weights, tuple) or len(weights) != len(times):
            raise ValueError(f"Give one afterpulse weight per time constant ({len(times)}), "
                             f"not {self.afterpulse_weights!r}")
        for weight in weights:
            check_number(weight, "Afterpulse weights")
        if times and sum(weights) <= 0:
            raise ValueError("Afterpulse weights must not all be 0")
        object.__setattr__(self, "afterpulse_weights",
                           tuple(w / sum(weights) for w in weights) if times else ())
        if self.afterpulse_probability > 0 and not times:
            raise ValueError("Afterpulsing needs at least one time constant (afterpulse_s)")
        _probability(self.crosstalk_orthogonal, "Orthogonal crosstalk probability")
        _probability(self.crosstalk_diagonal, "Diagonal crosstalk probability")

    @property
    def sigma_s(self):
        """The jitter's standard deviation, seconds."""
        return self.jitter_fwhm_s / (2.0 * math.sqrt(2.0 * math.log(2.0)))

    @property
    def crosstalk(self):
        """Whether an avalanche can fire a neighbour."""
        return self.crosstalk_orthogonal > 0 or self.crosstalk_diagonal > 0

    @property
    def afterpulsing(self):
        return self.afterpulse_probability > 0

    @property
    def avalanche_effects(self):
        """Whether the simulator needs its detector path (:mod:`~fliss.sim.scene.avalanches`):
        a paralysable dead time, a diffusion tail, afterpulses or crosstalk."""
        return bool(self.paralysable) or self.tail_fraction > 0 or self.afterpulsing \
            or self.crosstalk

    def dark_rates(self, pixels):
        """Dark count rate of each of ``pixels`` pixels, hertz (``float64`` array)."""
        # Two streams, so that pixel i's rate does not depend on the number of pixels
        spreads, hots = (np.random.default_rng(seed)
                         for seed in np.random.SeedSequence(self.dark_seed).spawn(2))
        spread = spreads.standard_normal(pixels)
        hot = hots.random(pixels) < self.hot_fraction
        rates = np.where(hot, float(self.hot_dark_count_hz), float(self.dark_count_hz))
        if self.dark_spread > 0:
            rates = rates * np.exp(self.dark_spread * spread)
        return rates

    def replace(self, **changes):
        """A copy with some fields changed."""
        from dataclasses import replace
        return replace(self, **changes)
