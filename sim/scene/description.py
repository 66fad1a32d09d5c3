"""What the scene simulator simulates: the victim pixel, its target, background and aggressors.

:class:`Scene` and :class:`Aggressor` describe one set-up (see :mod:`fliss.sim.scene` for the
model); the constants below are shared by the photon generation and the acquisitions.
"""

import math
from dataclasses import dataclass

import numpy as np

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.event import ADDRESS_BITS, TDC_LSB_S, TIMESTAMP_BITS
from ..models import delay as _delay
from ..models import scheduler as _scheduler
from .checks import check_number
from .detector import Detector
from .pixels import PixelArray


__all__ = ["SPEED_OF_LIGHT", "TDC_CODES", "FWHM_PER_SIGMA", "TRUNCATION_SIGMAS", "COUNTERS",
           "FINE_STEPS",
           "Aggressor", "Scene", "time_of_flight"]


#: Speed of light in vacuum, m/s.
SPEED_OF_LIGHT = 299_792_458.0

#: Number of TDC codes (histogram bins): ``2**13``.
TDC_CODES = 1 << TIMESTAMP_BITS

#: FWHM of a Gaussian in units of its standard deviation, ``2 * sqrt(2 * ln 2)``.
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))

#: Pulse shapes and jitter are Gaussians cut at this many standard deviations.
TRUNCATION_SIGMAS = 8.0

#: Sub-cycle delay steps the model offers (:attr:`Scene.fine_step`): steps per clock cycle.
FINE_STEPS = (1, 2, 4, 8, 16)

#: What happened to each photon, one counter per source (columns of the ``counts`` arrays).
COUNTERS = ("generated", "outside", "dead", "overwritten", "recorded")


def time_of_flight(distance_m):
    """Round-trip time of flight in seconds to a target ``distance_m`` away (``2 z / c``)."""
    return 2.0 * distance_m / SPEED_OF_LIGHT


@dataclass(frozen=True)
class Aggressor:
    """A second pulsed emitter seen by the victim's pixel.

    Parameters
    ----------
    period_cycles : float
        Pulse period in victim clock cycles; need not be whole (an aggressor has its own clock).
        The paper runs it at the victim's effective PRF.
    offset_s : float
        Time of its pulse ``j`` after the victim's nominal (undelayed) rising edge of pulse ``j``
        when both run at the same period: its first pulse rises ``offset_s`` after cycle
        ``1 + LATENCY``. The paper uses 75 ns. May be negative.
    detections_per_pulse : float
        Mean photons per aggressor pulse that reach the victim's pixel and would be detected by a
        ready SPAD.
    fwhm_s : float
        FWHM of its Gaussian pulse.
    tof_s : float or None
        Time of flight from the aggressor over the target to the victim's pixel; ``None`` takes the
        victim's own round trip (both emitters next to each other, as on the paper's board).
    mode, length, mask_width, seed, grid, key, iv
        Its own FLISS delays (see :class:`fliss.sim.models.scheduler.Settings`); ``mode="off"`` (the
        default) fires on a fixed period. With delays the period must be a whole number of cycles.
    ppm : float
        Frequency offset of its own oscillator from the victim's, in parts per million: its
        clock runs at ``clock_hz * (1 + ppm * 1e-6)``, so every time it sets in its own cycles
        (period, delays, the start) is shorter by that factor in the victim's time. 0: locked to
        the victim's clock, as on the paper's board.
    jitter_s : float
        RMS phase jitter of its oscillator: each of its pulses moves by an independent Gaussian
        time of this standard deviation (all photons of a pulse together).
    """

    period_cycles: float
    offset_s: float = 75e-9
    detections_per_pulse: float = 0.05
    fwhm_s: float = 2.1e-9
    tof_s: object = None
    mode: object = "off"
    length: object = None
    mask_width: object = None
    seed: int = 1
    grid: bool = False
    ppm: float = 0.0
    jitter_s: float = 0.0
    key: int = 0
    iv: int = 0

    def __post_init__(self):
        if isinstance(self.ppm, bool) or not isinstance(self.ppm, (int, float, np.integer,
                                                                     np.floating)) \
                or not math.isfinite(self.ppm) or abs(self.ppm) >= 1e5:
            raise ValueError(f"Aggressor frequency offset must be a finite number of ppm "
                             f"below 1e5 in size, not {self.ppm!r}")
        check_number(self.jitter_s, "Aggressor phase jitter (s RMS)")
        check_number(self.period_cycles, "Aggressor period (victim clock cycles)", positive=True)
        if isinstance(self.offset_s, bool) or \
                not isinstance(self.offset_s, (int, float, np.integer, np.floating)) or \
                not math.isfinite(self.offset_s):
            raise ValueError(f"Aggressor offset must be a finite number of seconds, "
                             f"not {self.offset_s!r}")
        check_number(self.detections_per_pulse, "Aggressor detections per pulse")
        check_number(self.fwhm_s, "Aggressor pulse FWHM (s)", positive=True)
        if self.tof_s is not None:
            check_number(self.tof_s, "Aggressor time of flight (s)")
        mode = _delay.check_settings(self.mode, length=self.length, mask_width=self.mask_width,
                                     seed=self.seed, key=self.key, iv=self.iv)
        if mode != _delay.DelayMode.OFF:
            if float(self.period_cycles) != int(self.period_cycles) or self.period_cycles < 2:
                raise ValueError(f"An aggressor with its own delays needs a whole number of clock "
                                 f"cycles of at least 2 as period, not {self.period_cycles!r}")
            self.settings().check()

    def settings(self):
        """Its delay settings as :class:`fliss.sim.models.scheduler.Settings`."""
        return _scheduler.Settings(
            mode=_delay.parse_mode(self.mode), length=self.length or 8,
            mask_width=self.mask_width or 6, seed=self.seed,
            period=int(self.period_cycles), grid=self.grid, key=self.key, iv=self.iv)

    @property
    def has_delays(self):
        return _delay.parse_mode(self.mode) != _delay.DelayMode.OFF


@dataclass(frozen=True)
class Scene:
    """A victim pixel looking at one target, with background and aggressors.

    Parameters
    ----------
    victim : Settings
        The victim's delay core settings (mode, L, Wm, seed, period in cycles, grid).
    clock_hz : float
        System clock of the victim.
    distance_m : float
        Target distance; the echo returns after ``2 z / c`` (4 m: 26.7 ns).
    detections_per_pulse : float
        Mean echo photons per victim pulse that a ready SPAD would detect. Keep it well below 1
        to stay out of pile-up.
    fwhm_s : float
        FWHM of the victim's Gaussian laser pulse (Table 1: 2.1 ns).
    aggressors : tuple of Aggressor
    background_hz : float
        Rate of ambient photons and dark counts at the pixel.
    dead_time_s : float
        SPAD dead time (non-paralysable).
    jitter_fwhm_s : float
        FWHM of the Gaussian timing jitter of SPAD and TDC.
    keep : str
        ``"last"`` (the paper's sensor) or ``"first"``: which detected photon the single-hit TDC
        keeps in each laser cycle.
    address : int
        Pixel address written into the events.
    fine_step : int
        Modelled sub-cycle delay steps: the victim's delays ``R`` (the gateware's sequences,
        bit-exact) count in steps of one clock cycle divided by ``fine_step`` (1, 2, 4, 8 or
        16), so its pulses fire ``R / fine_step`` cycles late. A model option: no gateware has
        it.
    pixels : PixelArray or None
        ``None``: one pixel (this class's ``distance_m`` and ``address``). A
        :class:`~fliss.sim.scene.pixels.PixelArray`: an imager, each pixel with its own target
        distance and reflectivity (``distance_m`` and ``address`` are then not used), simulated
        by :class:`~fliss.sim.scene.array.PixelSimulation` (:func:`~fliss.sim.scene.array.simulation_for`
        picks the simulation for a scene).
    detector : Detector or None
        The SPAD pixels' physics (:class:`~fliss.sim.scene.detector.Detector`: PDP, dark
        counts, dead time, timing response, afterpulsing, crosstalk). ``None``: a detector
        with this scene's ``dead_time_s`` and ``jitter_fwhm_s`` and nothing else (the
        simulator's behaviour before the detector). Given, its dead time and jitter are the
        scene's: ``dead_time_s`` and ``jitter_fwhm_s`` take its values, and a scene that sets
        them otherwise is refused.
    """

    victim: _scheduler.Settings = _scheduler.Settings(period=80)
    clock_hz: float = DEFAULT_CLOCK_HZ
    distance_m: float = 4.0
    detections_per_pulse: float = 0.05
    fwhm_s: float = 2.1e-9
    aggressors: tuple = ()
    background_hz: float = 1e5
    dead_time_s: float = 20e-9
    jitter_fwhm_s: float = 100e-12
    keep: str = "last"
    address: int = 0
    fine_step: int = 1
    pixels: object = None
    detector: object = None

    def __post_init__(self):
        if not isinstance(self.victim, _scheduler.Settings):
            raise ValueError(f"Victim settings must be a fliss.sim.models.scheduler.Settings, "
                             f"not {self.victim!r}")
        self.victim.check()
        check_number(self.clock_hz, "Clock frequency (Hz)", positive=True)
        check_number(self.distance_m, "Target distance (m)")
        check_number(self.detections_per_pulse, "Detections per pulse")
        check_number(self.fwhm_s, "Pulse FWHM (s)", positive=True)
        check_number(self.background_hz, "Background rate (Hz)")
        check_number(self.dead_time_s, "Dead time (s)")
        check_number(self.jitter_fwhm_s, "Jitter FWHM (s)")
        if self.keep not in ("first", "last"):
            raise ValueError(f"The TDC keeps the 'first' or the 'last' photon, not {self.keep!r}")
        if isinstance(self.address, bool) or not isinstance(self.address, (int, np.integer)) \
                or not 0 <= self.address < (1 << ADDRESS_BITS):
            raise ValueError(f"Pixel address must be an integer from 0 to "
                             f"{(1 << ADDRESS_BITS) - 1}, not {self.address!r}")
        if isinstance(self.fine_step, bool) or self.fine_step not in FINE_STEPS:
            raise ValueError(f"Fine delay step must be one of {', '.join(map(str, FINE_STEPS))} "
                             f"(steps per clock cycle), not {self.fine_step!r}")
        if self.pixels is not None:
            if not isinstance(self.pixels, PixelArray):
                raise ValueError(f"Scene pixels must be a PixelArray or None, not "
                                 f"{self.pixels!r}")
        if self.detector is not None:
            if not isinstance(self.detector, Detector):
                raise ValueError(f"Scene detector must be a Detector or None, not "
                                 f"{self.detector!r}")
            for name in ("dead_time_s", "jitter_fwhm_s"):
                own, given = getattr(self.detector, name), getattr(self, name)
                if given != own and given != getattr(Scene, name):
                    raise ValueError(f"The scene's {name} ({given!r}) differs from its "
                                     f"detector's ({own!r}): set it in the detector")
                object.__setattr__(self, name, own)
        object.__setattr__(self, "aggressors", tuple(self.aggressors))
        for aggressor in self.aggressors:
            if not isinstance(aggressor, Aggressor):
                raise ValueError(f"Aggressors must be Aggressor objects, not {aggressor!r}")

    @property
    def lsb_per_cycle(self):
        """Clock period in TDC LSBs (250 at 80 MHz)."""
        return 1.0 / (self.clock_hz * TDC_LSB_S)

    @property
    def tof_s(self):
        """The victim's round-trip time of flight, in seconds."""
        return time_of_flight(self.distance_m)

    @property
    def spad(self):
        """The scene's :class:`~fliss.sim.scene.detector.Detector` (``detector``, or the
        default one with the scene's dead time and jitter)."""
        if self.detector is not None:
            return self.detector
        return Detector(dead_time_s=self.dead_time_s, jitter_fwhm_s=self.jitter_fwhm_s)

    @property
    def sources(self):
        """Names of the photon sources, in the order of the rows of the ``counts`` arrays:
        then ``"afterpulse"`` when the detector afterpulses, ``"crosstalk"`` when a pixel
        array's detector has crosstalk."""
        spad = self.spad
        return ("signal", "background") + tuple(f"aggressor {index + 1}"
                                                for index in range(len(self.aggressors))) + \
            (("afterpulse",) if spad.afterpulsing else ()) + \
            (("crosstalk",) if spad.crosstalk and self.pixels is not None else ())

    def replace(self, **changes):
        """A copy with some fields changed."""
        from dataclasses import replace
        return replace(self, **changes)
