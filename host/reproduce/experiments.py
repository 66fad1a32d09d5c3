"""The experiments of ``fliss reproduce``: the paper's settings, run on the scene simulator.

The parameters are those of the paper (Table 1 and section 6): 80 MHz clock, 1 MHz nominal PRF,
target at 4 m, 2.1 ns laser pulses, an aggressor 75 ns after the victim running at the victim's
effective PRF, integration times of 10, 30 and 100 ms, complete m-sequences of L = 3 to 6 and
masks of Wm = 1 to 6 bits on the 32-bit register, 300 acquisitions. The photon rates, background,
dead time and jitter are not in the paper; their defaults (see ``--help`` and ``docs/results.md``)
come from physics, not from fitting the paper's numbers.

For every setting the run records, per acquisition, the victim's peak (ToF, FWHM, height) and the
suppression ratio S of equation 10. Victim and aggressor peaks are told apart by reference runs,
as on a bench: the victim alone with FLISS off (which is also the reference of Figure 11), and
the aggressor alone (victim laser off) with the same delays, which shows where the aggressor's
peaks fall in each acquisition.
"""

import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from ...hdl.clock import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles
from ...sim.models import delay as delay_model
from ...sim.models import scheduler as scheduler_model
from ...sim.scene import Aggressor, Scene, acquire
from .. import analysis
from ..sweep.engine import cluster, compute


__all__ = ["DISTANCE_M", "PULSE_FWHM_S", "AGGRESSOR_OFFSET_S", "Config", "Job", "ReproductionError",
           "victim_of", "run_experiments"]


#: Table 1 of the paper.
DISTANCE_M = 4.0
PULSE_FWHM_S = 2.1e-9
AGGRESSOR_OFFSET_S = 75e-9


@dataclass(frozen=True)
class Config:
    """Everything a reproduction depends on."""
    acquisitions: int = 300
    t_int_s: tuple = (10e-3, 30e-3, 100e-3)
    lengths: tuple = (3, 4, 5, 6)
    mask_widths: tuple = (1, 2, 3, 4, 5, 6)
    clock_hz: float = DEFAULT_CLOCK_HZ
    prf_hz: float = DEFAULT_PRF_HZ
    signal: float = 0.05
    aggressor: float = 0.05
    background_hz: float = 1e5
    dead_time_s: float = 20e-9
    jitter_fwhm_s: float = 100e-12
    keep: str = "last"
    aggressor_prf: str = "effective"
    victim_seed: int = 1
    seed: int = 2019

    @property
    def period(self):
        return period_cycles(self.clock_hz, self.prf_hz)

    def check(self):
        if self.acquisitions < 1:
            raise ValueError(f"--acquisitions must be at least 1, not {self.acquisitions}")
        if self.aggressor_prf not in ("effective", "nominal"):
            raise ValueError(f"The aggressor runs at the 'effective' or the 'nominal' PRF of the "
                             f"victim, not {self.aggressor_prf!r}")
        if not self.t_int_s:
            raise ValueError("Give at least one integration time")
        for t_int_s in self.t_int_s:
            if not (math.isfinite(t_int_s) and t_int_s > 0):
                raise ValueError(f"--t-int must be a positive time (10ms), not {t_int_s:g} s")
        for length in self.lengths:
            if not 2 <= length <= 16:
                raise ValueError(f"--lengths must be from 2 to 16 (complete sequences), "
                                 f"not {length}")
        for width in self.mask_widths:
            delay_model.check_settings("masked", mask_width=width)
        # Builds every scene once, so bad rates or settings fail before any work starts.
        for victim, aggressor_period in self.settings():
            self.scene(victim, aggressor_period)
        return self

    def victim(self, mode="off", **setting):
        return scheduler_model.Settings(mode=delay_model.parse_mode(mode), period=self.period,
                                        seed=self.victim_seed, **setting).check()

    def aggressor_period(self, victim):
        """Aggressor period in cycles: the victim's effective period (the paper) or nominal."""
        if self.aggressor_prf == "nominal":
            return float(victim.period)
        return self.effective_period(victim)

    def effective_period(self, victim):
        """Victim's mean pulse interval in cycles, ``T + E(R)`` (equation 4)."""
        mean = delay_model.mean_delay(victim.mode, length=victim.length,
                                      mask_width=victim.mask_width)
        return victim.period + float(mean)

    def scene(self, victim, aggressor_period=None, *, signal=True):
        aggressors = ()
        if aggressor_period is not None:
            aggressors = (Aggressor(period_cycles=aggressor_period, offset_s=AGGRESSOR_OFFSET_S,
                                    detections_per_pulse=self.aggressor,
                                    fwhm_s=PULSE_FWHM_S),)
        return Scene(victim=victim, clock_hz=self.clock_hz, distance_m=DISTANCE_M,
                     detections_per_pulse=self.signal if signal else 0.0, fwhm_s=PULSE_FWHM_S,
                     aggressors=aggressors, background_hz=self.background_hz,
                     dead_time_s=self.dead_time_s, jitter_fwhm_s=self.jitter_fwhm_s,
                     keep=self.keep)

    def settings(self):
        off = self.victim()
        yield off, None
        yield off, float(off.period)
        for length in self.lengths:
            victim = self.victim("mseq", length=length)
            yield victim, self.aggressor_period(victim)
        for width in self.mask_widths:
            victim = self.victim("masked", mask_width=width)
            yield victim, self.aggressor_period(victim)


class ReproductionError(Exception):
    """A reproduction that cannot go on (for instance the victim's peak is not found)."""


# Jobs ------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Job:
    """One setting to run: kind, L or Wm, integration time, index (seeds its statistics)."""
    kind: str           # "reference", "off", "mseq", "masked"
    setting: int        # L or Wm; 0 for the others
    t_int_s: float
    index: int
    victim_s: float = math.nan

    @property
    def name(self):
        label = {"reference": "victim alone", "off": "FLISS off",
                 "mseq": f"mseq L={self.setting}", "masked": f"masked Wm={self.setting}"}
        return f"{label[self.kind]}, T_int {self.t_int_s * 1e3:g} ms"


def victim_of(config, job):
    """The victim's delay settings of ``job``."""
    if job.kind == "mseq":
        return config.victim("mseq", length=job.setting)
    if job.kind == "masked":
        return config.victim("masked", mask_width=job.setting)
    return config.victim()


def _weight(config, job):
    """Laser cycles the job simulates (for the progress bar)."""
    victim = victim_of(config, job)
    runs = 1 if job.kind == "reference" else 2
    return runs * config.acquisitions * job.t_int_s * config.clock_hz / \
        config.effective_period(victim)


def _victim_peak(histogram):
    peaks = analysis.find_peaks(histogram)
    if not peaks:
        return None
    return peaks[0]


def _run_job(config, job):
    """One setting: its acquisitions, analysed. Runs in a worker process."""
    victim = victim_of(config, job)
    seeds = np.random.SeedSequence([config.seed, job.index]).spawn(2)
    n = config.acquisitions
    result = {"job": job, "cycles": 0.0}
    if job.kind == "reference":
        runs = acquire(config.scene(victim), job.t_int_s, n, seed=seeds[0])
        peaks = [_victim_peak(histogram) for histogram in runs.histograms]
        result.update(
            tof=np.array([p.position_s if p else math.nan for p in peaks]),
            fwhm=np.array([p.fwhm_s if p else math.nan for p in peaks]),
            pv=np.array([p.height if p else math.nan for p in peaks]),
            example=runs.histograms[0], counts=runs.counts.sum(axis=0),
            cycles=float(runs.cycles.mean()))
        return result

    aggressor_period = config.aggressor_period(victim)
    scene = config.scene(victim, aggressor_period)
    runs = acquire(scene, job.t_int_s, n, seed=seeds[0])
    alone = acquire(config.scene(victim, aggressor_period, signal=False), job.t_int_s, n,
                    seed=seeds[1])
    keys = ("s_db", "pv", "pa", "limited", "tof", "fwhm", "aggressor_peaks")
    values = {key: np.full(n, math.nan) for key in keys}
    example_peaks = []
    for index, (histogram, reference) in enumerate(zip(runs.histograms, alone.histograms)):
        positions = [peak.position_s for peak in analysis.find_peaks(reference)]
        try:
            measured = analysis.suppression(histogram, job.victim_s, positions)
        except ValueError:
            continue                        # victim peak lost in this acquisition: NaN
        values["s_db"][index] = measured.s_db
        values["pv"][index] = measured.pv
        values["pa"][index] = measured.pa
        values["limited"][index] = measured.limited
        values["tof"][index] = measured.victim.position_s
        values["fwhm"][index] = measured.victim.fwhm_s
        values["aggressor_peaks"][index] = len(measured.aggressors)
        if index == 0:
            example_peaks = [(peak.position_s, peak.height) for peak in measured.aggressors]
            example_peaks.append(("victim", measured.victim.position_s, measured.victim.height,
                                  measured.pa, measured.limited))
    result.update(values, example=runs.histograms[0], example_alone=alone.histograms[0],
                  example_peaks=example_peaks, counts=runs.counts.sum(axis=0),
                  sources=runs.sources, cycles=float(runs.cycles.mean()))
    return result


class _Progress:
    """A progress bar on stderr, weighted by simulated laser cycles."""

    def __init__(self, total, stream=sys.stderr, width=32):
        self.total, self.done, self.stream, self.width = total, 0.0, stream, width
        self.enabled = stream is not None
        self.start = time.monotonic()
        self.tty = hasattr(stream, "isatty") and stream.isatty()
        self._last_tenth = -1

    def advance(self, amount, label):
        self.done += amount
        if not self.enabled:
            return
        fraction = min(self.done / self.total, 1.0) if self.total else 1.0
        elapsed = time.monotonic() - self.start
        filled = int(round(fraction * self.width))
        bar = "#" * filled + "." * (self.width - filled)
        line = f"[{bar}] {fraction * 100:5.1f}%  {elapsed:6.1f} s  {label}"
        if self.tty:
            self.stream.write("\r" + line[:100].ljust(100))
            self.stream.flush()
        elif int(fraction * 10) != self._last_tenth:
            self._last_tenth = int(fraction * 10)
            self.stream.write(line + "\n")
            self.stream.flush()

    def close(self):
        if self.enabled and self.tty:
            self.stream.write("\n")
            self.stream.flush()


def _execute(client, config, jobs, progress):
    """Run ``jobs`` as points of the sweep engine; their results in job order. Ctrl-C cancels
    what is left and raises :exc:`KeyboardInterrupt` once the workers have stopped."""
    by_index = {job.index: job for job in jobs}
    results = {}

    def finished(index, result, elapsed_s):
        results[index] = result
        progress.advance(_weight(config, by_index[index]), by_index[index].name)

    tasks = {job.index: (_run_job, (config, job)) for job in jobs}
    if not compute(client, tasks, finished):
        progress.close()
        raise KeyboardInterrupt
    return [results[index] for index in sorted(results)]


def run_experiments(config, *, workers=1, stream=sys.stderr, scheduler=None):
    """Run every setting of ``config``, with a progress bar on ``stream`` (``None``: none).

    The settings run on the sweep engine (:mod:`~fliss.host.sweep.engine`): a ``LocalCluster`` of
    ``workers`` processes (one thread when ``workers`` is 1), or the Dask ``scheduler`` given.

    Returns ``(by_t, results, elapsed)``: the reference results by integration time, the results
    of the other settings in order, and the time taken in seconds. Raises
    :class:`ReproductionError` if the victim's peak is missing from a reference run.
    """
    t_max = max(config.t_int_s)
    references = [Job("reference", 0, t, index) for index, t in enumerate(config.t_int_s)]
    others = [("off", 0, t_max)] + \
        [("mseq", length, t) for t in config.t_int_s for length in config.lengths] + \
        [("masked", width, t_max) for width in config.mask_widths]
    total = sum(_weight(config, job) for job in references) + \
        sum(_weight(config, Job(kind, setting, t, 0)) for kind, setting, t in others)
    progress = _Progress(total, stream)
    started = time.monotonic()
    with cluster(workers, processes=workers > 1, scheduler=scheduler) as client:
        return _run_all(client, config, references, others, progress, started)


def _run_all(client, config, references, others, progress, started):
    reference_results = _execute(client, config, references, progress)
    by_t = {}
    for result in reference_results:
        tof = analysis.mean_std(result["tof"])[0]
        if not math.isfinite(tof):
            progress.close()
            raise ReproductionError(f"The victim's peak was not found in the reference run at "
                                    f"T_int = {result['job'].t_int_s * 1e3:g} ms: raise the signal "
                                    f"rate or the integration time")
        by_t[result["job"].t_int_s] = result

    def victim_position(t):
        return analysis.mean_std(by_t[t]["tof"])[0]

    jobs = [Job(kind, setting, t, len(references) + index, victim_position(t))
            for index, (kind, setting, t) in enumerate(others)]
    results = _execute(client, config, jobs, progress)
    progress.close()
    elapsed = time.monotonic() - started
    return by_t, results, elapsed
