"""Photon-level Monte Carlo of a TCSPC LiDAR pixel with FLISS: victim, aggressors, background.

The model follows section 5 of the paper. The victim fires at the laser rising edges that the
reference model of the delay core gives (:mod:`fliss.sim.models.scheduler`, the same delay sequences and
seeds as the gateware), and its TDC starts on the same edge, so the victim's own photons keep their
time of flight (equation 5) while the photons of an aggressor, fired on its own schedule, move by
``-T_rnd`` in the victim's frame (equation 6).

Model
-----
* Time runs in TDC LSBs (50 ps) as ``float64``; cycle ``0`` is the first take cycle of the victim's
  scheduler, pulse ``k`` rises (and its TDC starts) in cycle ``fire_cycles(...)[k] + LATENCY``.
* A pulsed source (the victim's own echo, each aggressor) gives per pulse a Poisson number of
  detections with mean ``detections_per_pulse``, spread as a Gaussian of the laser's FWHM around the
  pulse's arrival time, widened by the SPAD and TDC timing jitter (Gaussians add in quadrature).
  Both Gaussians are cut at :data:`TRUNCATION_SIGMAS` standard deviations.
* Ambient light and dark counts form a Poisson process of rate ``background_hz``. It is drawn only
  where it can matter: in each TDC window and in the dead time just before it.
* The SPAD is the scene's detector (:class:`Detector`, :mod:`~fliss.sim.scene.detector`: PDP,
  dark counts per pixel, dead time paralysable or not, timing response, afterpulsing,
  crosstalk; :data:`PRESETS` by name). By default it is non-paralysable: after a detection it
  is blind for ``dead_time_s``. A photon that arrives while it is blind is lost (counted as
  ``dead``). The SPAD's state carries over from window to window; the background between windows is not drawn, so a chain of blocked photons reaching
  from the gap into a window is not modelled (its effect is of order ``(background_hz *
  dead_time_s)**2``).
* The TDC of pulse ``k`` is live from its start until ``2**13`` LSBs later or until the next start,
  whichever comes first; it keeps one photon per laser cycle, the first or the last detected one
  (the paper's sensor keeps the last). Photons outside every window are counted as ``outside``.
* An event is what the sensor's TDC interface delivers: timestamp ``floor((t - start) / LSB)``,
  pixel address, collision flag (always 0: one pixel is modelled) and laser cycle index ``pulse``
  (modulo ``2**32``, as the gateware counter wraps).

Every photon drawn is counted exactly once per source: ``generated = outside + dead + overwritten +
recorded``.

The simulation streams: :class:`Simulation` works through the laser cycles a chunk at a time, so
memory stays bounded whatever the integration time. The victim's TDC starts come from the
reference scheduler, or, in closed loop with a simulated gateware, from :meth:`Simulation.feed`.
:func:`acquire` cuts one continuous run into acquisitions of a given integration time and returns
their histograms (``TDC_CODES`` bins, as the histogram engine delivers them).

A pixel array (an imager: a depth map, shared background and flash aggressors, a column
sensor with one TDC bank or one TDC per pixel) is a :class:`Scene` with ``pixels``
(:class:`PixelArray`, :func:`line_pixels`; model in :mod:`~fliss.sim.scene.pixels`), simulated
by :class:`PixelSimulation`; :func:`simulation_for` picks the simulation a scene needs.

This module gathers the simulator's public names; the parts live in
:mod:`~fliss.sim.scene.description` (the scene and its constants), :mod:`~fliss.sim.scene.pulses`
(laser edges and pulse trains), :mod:`~fliss.sim.scene.draws` (Poisson counts drawn ahead),
:mod:`~fliss.sim.scene.photons` (photon generation, the steps),
:mod:`~fliss.sim.scene.detection` and :mod:`~fliss.sim.scene.few` (detection) and :mod:`~fliss.sim.scene.acquisition` (acquisitions and histograms). The delay
sequences come from :class:`fliss.sim.models.delay.DelayStream`.
"""

from .acquisition import Acquisitions, acquire, histogram
from .description import (COUNTERS, FWHM_PER_SIGMA, SPEED_OF_LIGHT, TDC_CODES, TRUNCATION_SIGMAS,
                          Aggressor, Scene, time_of_flight)
from .detector import Detector
from .presets import PRESETS
from .array import PixelChunk, PixelSimulation, simulation_for
from .photons import Chunk, Simulation
from .pixels import (COLLISION_WINDOW_S, LINE_PIXELS, REFERENCE_DISTANCE_M, SCENE_NAMES,
                     SENSOR_KINDS, PixelArray, line_pixels, pixels_named)


__all__ = ["SPEED_OF_LIGHT", "TDC_CODES", "FWHM_PER_SIGMA", "TRUNCATION_SIGMAS", "COUNTERS",
           "Aggressor", "Scene", "Chunk", "Simulation", "Acquisitions",
           "acquire", "histogram", "time_of_flight",
           "SENSOR_KINDS", "COLLISION_WINDOW_S", "REFERENCE_DISTANCE_M", "LINE_PIXELS",
           "SCENE_NAMES", "PixelArray", "line_pixels", "pixels_named", "PixelChunk",
           "PixelSimulation", "simulation_for", "Detector", "PRESETS"]
