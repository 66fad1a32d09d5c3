"""The attacker in the photon-level scene simulator: a victim, what the attacker saw of it, and
the attacker's ghost in the victim's histograms.

:class:`Victim` gives the victim's delays for every source an experiment compares (``off``,
``mseq``, ``masked``, ``keyed`` from :mod:`fliss.sim.models.trivium`, and ``random``: independent
uniform delays of ``Wm`` bits, the unpredictable reference). :func:`run` feeds the victim's TDC
starts and the attacker's triggers (:attr:`fliss.sim.studies.attacker.AttackResult.edges`) to
:class:`fliss.sim.scene.photons.Simulation` as an external aggressor placed at the ghost's
time of flight, and returns the victim's histograms a fixed number of pulses at a time. The
ghost is measured by the host's peak finder like every other aggressor.
"""

from dataclasses import dataclass

import numpy as np

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.delay.settings import MAX_MASK_WIDTH, as_int
from ..models import delay as _delay
from ..models import scheduler as _scheduler
from ..models import trivium as _trivium
from ..scene.acquisition import histogram as _histogram
from ..scene.description import Aggressor, Scene, TDC_CODES, time_of_flight
from ..scene.photons import Simulation


__all__ = ["SOURCES", "Victim", "Histograms", "run"]


#: Delay sources an experiment can give the victim.
SOURCES = ("off", "mseq", "masked", "keyed", "random")


@dataclass(frozen=True)
class Victim:
    """A victim's delay source and schedule.

    Parameters
    ----------
    mode : str
        One of :data:`SOURCES`.
    length : int or None
        ``L`` of ``mseq``.
    mask_width : int or None
        ``Wm`` of ``masked``, ``keyed`` and ``random``.
    seed : int
        Register seed (``mseq``, ``masked``) or generator seed (``random``).
    key, iv : int or bytes
        Trivium key and IV of ``keyed`` (see :mod:`fliss.sim.models.trivium`).
    period : int
        Nominal period ``T`` in clock cycles.
    grid : bool
        Grid mode instead of interval mode.
    """

    mode: str = "off"
    length: object = None
    mask_width: object = None
    seed: int = 1
    key: object = 0
    iv: object = 0
    period: int = 80
    grid: bool = False

    def __post_init__(self):
        if self.mode not in SOURCES:
            raise ValueError(f"Victim source must be one of {', '.join(SOURCES)}, "
                             f"not {self.mode!r}")
        if self.mode in ("keyed", "random"):
            if isinstance(self.mask_width, bool) or \
                    not isinstance(self.mask_width, (int, np.integer)) or \
                    not 1 <= self.mask_width <= MAX_MASK_WIDTH:
                raise ValueError(f"Mask width must be an integer from 1 to {MAX_MASK_WIDTH}, "
                                 f"not {self.mask_width!r}")
            if self.mode == "keyed":
                as_int(self.key, "key")
                as_int(self.iv, "IV")
            max_delay = (1 << self.mask_width) - 1
        else:
            _delay.check_settings(self.mode, length=self.length, mask_width=self.mask_width,
                                  seed=self.seed)
            max_delay = _delay.max_delay(self.mode, length=self.length,
                                         mask_width=self.mask_width)
        _scheduler.check_schedule(self.period, 1, grid=self.grid, max_delay=max_delay)

    @property
    def label(self):
        if self.mode == "mseq":
            return f"mseq L={self.length}"
        if self.mode == "off":
            return "off"
        return f"{self.mode} Wm={self.mask_width}"

    def delays(self, count):
        """The delays of the first ``count`` pulses, in clock cycles."""
        if self.mode == "keyed":
            return _trivium.keyed_delays(self.key, self.iv, self.mask_width, count)
        if self.mode == "random":
            rng = np.random.default_rng(self.seed)
            return rng.integers(0, 1 << self.mask_width, count, dtype=np.int64)
        return _delay.delays(self.mode, count, length=self.length, mask_width=self.mask_width,
                             seed=self.seed)

    def start_cycles(self, count, start=0):
        """TDC start (laser rising edge) of the first ``count`` pulses, in clock cycles."""
        fires = _scheduler.fire_cycles(self.delays(count), self.period, grid=self.grid,
                                       start=start)
        return fires + _scheduler.LATENCY


@dataclass
class Histograms:
    """The victim's histograms, ``pulses`` laser cycles each.

    Attributes
    ----------
    histograms : numpy.ndarray
        ``(acquisitions, TDC_CODES)``.
    end_s : numpy.ndarray
        Time of the last TDC start of each acquisition, from the first pulse.
    victim_s, ghost_s : float
        Where the victim's and the ghost's peaks belong (their times of flight).
    counts : numpy.ndarray
        Photon counters over the run, ``(sources, counters)``.
    """

    histograms: np.ndarray
    end_s: np.ndarray
    victim_s: float
    ghost_s: float
    counts: np.ndarray


def run(victim, starts, edges, pulses_per_acquisition, *, ghost_m=10.0, distance_m=4.0,
        detections_per_pulse=0.05, ghost_detections_per_pulse=0.05, clock_hz=DEFAULT_CLOCK_HZ,
        seed=None):
    """The victim's histograms with the attacker firing on ``edges``.

    Parameters
    ----------
    victim : Victim
    starts : numpy.ndarray
        The victim's TDC starts in clock cycles (:meth:`Victim.start_cycles`); all but the last
        are simulated.
    edges : numpy.ndarray
        The attacker's triggers in clock cycles: its pulse reaches the victim's pixel the time
        of flight of ``ghost_m`` after each.
    pulses_per_acquisition : int
        Victim laser cycles in each histogram.
    """
    scene = Scene(victim=_scheduler.Settings(period=victim.period), clock_hz=clock_hz,
                  distance_m=distance_m, detections_per_pulse=detections_per_pulse,
                  aggressors=(Aggressor(period_cycles=victim.period, offset_s=0.0,
                                        tof_s=time_of_flight(ghost_m),
                                        detections_per_pulse=ghost_detections_per_pulse),))
    simulation = Simulation(scene, seed=seed, chunk_cycles=max(int(pulses_per_acquisition), 1),
                            external_starts=True, external_aggressors=True)
    simulation.feed(np.asarray(starts, dtype=np.int64))
    simulation.feed_aggressor(0, np.asarray(edges, dtype=np.int64))
    acquisitions = (len(starts) - 1) // pulses_per_acquisition
    histograms = np.zeros((acquisitions, TDC_CODES), dtype=np.int64)
    end_s = np.zeros(acquisitions)
    for index in range(acquisitions):
        chunk = simulation.step(pulses_per_acquisition)
        histograms[index] = _histogram(chunk.events)
        end_s[index] = (chunk.start_cycles[-1] - starts[0]) / clock_hz
    return Histograms(histograms, end_s, time_of_flight(distance_m), time_of_flight(ghost_m),
                      simulation.counts.copy())
