"""``fliss reproduce``: the experiments of section 6 of the paper, on the scene simulator.

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

import argparse
import csv
import math
import os
import re
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass

import numpy as np

from ..hdl import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles
from ..sim import delay as delay_model
from ..sim import scheduler as scheduler_model
from ..sim.scene import Aggressor, COUNTERS, Scene, acquire
from . import analysis
from .cli import UserError
from .units import format_frequency, parse_frequency, parse_time


__all__ = ["PAPER", "Config", "register", "run", "reproduce"]


#: What the paper reports (section 6, Figures 7 to 12, Table 2), as text for the tables.
PAPER = {
    "victim_tof": "132.1 ns (not calibrated: includes a constant offset)",
    "victim_fwhm": "1.65 ns",
    "aggressor_delta": "72.7 ns (204.8 ns - 132.1 ns)",
    "aggressor_fwhm": "1.65 ns",
    "s_mseq": "rises with L, up to 35 dB at L = 6 (complete sequences); T_int has marginal effect",
    "s_masked": "rises with Wm, up to 50 dB at Wm = 6 (T_int = 100 ms)",
    "dev_tof": "< 0.15 %, independent of L and T_int",
    "dev_fwhm": "within 3 %",
    "dev_pv": "close to 0 for L <= 4, declining for larger L",
    "prf": {3: "963.9 kHz", 4: "919.5 kHz", 5: "842.1 kHz", 6: "720.7 kHz"},
}

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


# Jobs ------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Job:
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


def _victim_of(config, job):
    if job.kind == "mseq":
        return config.victim("mseq", length=job.setting)
    if job.kind == "masked":
        return config.victim("masked", mask_width=job.setting)
    return config.victim()


def _weight(config, job):
    """Laser cycles the job simulates (for the progress bar)."""
    victim = _victim_of(config, job)
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
    victim = _victim_of(config, job)
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


def _execute(config, jobs, workers, progress):
    results = []
    if workers <= 1:
        for job in jobs:
            results.append(_run_job(config, job))
            progress.advance(_weight(config, job), job.name)
        return results
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(_run_job, config, job): job for job in jobs}
        for future in as_completed(futures):
            job = futures[future]
            results.append(future.result())
            progress.advance(_weight(config, job), job.name)
    return sorted(results, key=lambda result: result["job"].index)


def reproduce(config, out_dir, *, workers=1, figures=True, stream=sys.stderr):
    """Run the reproduction; write CSV, Markdown and PNG files into ``out_dir``.

    Returns the list of result rows (dicts), one per setting.
    """
    config.check()
    t_max = max(config.t_int_s)
    references = [_Job("reference", 0, t, index) for index, t in enumerate(config.t_int_s)]
    others = [("off", 0, t_max)] + \
        [("mseq", length, t) for t in config.t_int_s for length in config.lengths] + \
        [("masked", width, t_max) for width in config.mask_widths]
    total = sum(_weight(config, job) for job in references) + \
        sum(_weight(config, _Job(kind, setting, t, 0)) for kind, setting, t in others)
    progress = _Progress(total, stream)
    started = time.monotonic()
    reference_results = _execute(config, references, workers, progress)
    by_t = {}
    for result in reference_results:
        tof = analysis.mean_std(result["tof"])[0]
        if not math.isfinite(tof):
            progress.close()
            raise UserError(f"The victim's peak was not found in the reference run at T_int = "
                            f"{result['job'].t_int_s * 1e3:g} ms: raise the signal rate or the "
                            f"integration time")
        by_t[result["job"].t_int_s] = result
    def victim_position(t):
        return analysis.mean_std(by_t[t]["tof"])[0]

    jobs = [_Job(kind, setting, t, len(references) + index, victim_position(t))
            for index, (kind, setting, t) in enumerate(others)]
    results = _execute(config, jobs, workers, progress)
    progress.close()
    elapsed = time.monotonic() - started

    os.makedirs(out_dir, exist_ok=True)
    rows = _rows(config, by_t, results)
    _write_csv(os.path.join(out_dir, "results.csv"), rows)
    written = ["results.csv", "results.md"]
    if figures:
        written += _figures(config, by_t, results, out_dir)
    _write_markdown(os.path.join(out_dir, "results.md"), config, rows, by_t, results, elapsed,
                    workers, written)
    return rows


# Results ---------------------------------------------------------------------------------------

def _rows(config, by_t, results):
    rows = []

    def stats(values, scale=1.0):
        mean, std = analysis.mean_std(np.asarray(values, dtype=float) * scale)
        return mean, std

    for t, result in sorted(by_t.items()):
        tof, fwhm, pv = stats(result["tof"], 1e9), stats(result["fwhm"], 1e9), stats(result["pv"])
        rows.append(dict(experiment="victim alone (Fig. 7)", setting="FLISS off",
                         t_int_ms=t * 1e3, prf_eff_khz=config.prf_hz / 1e3,
                         acquisitions=config.acquisitions, s_db=math.nan, s_std_db=math.nan,
                         s_limited=math.nan, tof_ns=tof[0], tof_std_ns=tof[1], fwhm_ns=fwhm[0],
                         fwhm_std_ns=fwhm[1], pv=pv[0], pv_std=pv[1], dev_tof_pct=math.nan,
                         dev_tof_std_pct=math.nan, dev_fwhm_pct=math.nan,
                         dev_fwhm_std_pct=math.nan, dev_pv_pct=math.nan, dev_pv_std_pct=math.nan,
                         paper=f"ToF {PAPER['victim_tof']}; FWHM {PAPER['victim_fwhm']}"
                         if t == max(by_t) else ""))
    for result in results:
        job = result["job"]
        reference = by_t[job.t_int_s] if job.t_int_s in by_t else by_t[max(by_t)]
        victim = _victim_of(config, job)
        prf = config.clock_hz / config.effective_period(victim)
        ref_tof = analysis.mean_std(reference["tof"])[0]
        ref_fwhm = analysis.mean_std(reference["fwhm"])[0]
        ref_pv = analysis.mean_std(reference["pv"])[0]
        dev = {name: stats(analysis.relative_deviation(result[key], ref), 100.0)
               for name, key, ref in (("tof", "tof", ref_tof), ("fwhm", "fwhm", ref_fwhm),
                                      ("pv", "pv", ref_pv))}
        if job.kind == "off":
            experiment, setting = "aggressor, FLISS off (Fig. 8)", "FLISS off"
            paper = f"aggressor {PAPER['aggressor_delta']} after the victim"
        elif job.kind == "mseq":
            experiment, setting = "FLISS, complete m-sequence (Figs. 9-11)", f"L = {job.setting}"
            paper = f"PRF_eff {PAPER['prf'].get(job.setting, '-')}"
            if job.setting == 6 and job.t_int_s == max(config.t_int_s):
                paper += "; S up to 35 dB"
        else:
            experiment, setting = "FLISS, masked 32-bit LFSR (Fig. 12)", f"Wm = {job.setting}"
            paper = "S up to 50 dB" if job.setting == 6 else ""
        s = stats(result["s_db"])
        limited = np.asarray(result["limited"], dtype=float)
        tof, fwhm, pv = stats(result["tof"], 1e9), stats(result["fwhm"], 1e9), stats(result["pv"])
        rows.append(dict(experiment=experiment, setting=setting, t_int_ms=job.t_int_s * 1e3,
                         prf_eff_khz=prf / 1e3, acquisitions=config.acquisitions,
                         s_db=s[0], s_std_db=s[1],
                         s_limited=float(np.nanmean(limited)) if np.isfinite(limited).any()
                         else math.nan,
                         tof_ns=tof[0], tof_std_ns=tof[1], fwhm_ns=fwhm[0], fwhm_std_ns=fwhm[1],
                         pv=pv[0], pv_std=pv[1],
                         dev_tof_pct=dev["tof"][0], dev_tof_std_pct=dev["tof"][1],
                         dev_fwhm_pct=dev["fwhm"][0], dev_fwhm_std_pct=dev["fwhm"][1],
                         dev_pv_pct=dev["pv"][0], dev_pv_std_pct=dev["pv"][1], paper=paper))
    return rows


_COLUMNS = ["experiment", "setting", "t_int_ms", "prf_eff_khz", "acquisitions", "s_db",
            "s_std_db", "s_limited", "tof_ns", "tof_std_ns", "fwhm_ns", "fwhm_std_ns", "pv",
            "pv_std", "dev_tof_pct", "dev_tof_std_pct", "dev_fwhm_pct", "dev_fwhm_std_pct",
            "dev_pv_pct", "dev_pv_std_pct", "paper"]


def _write_csv(path, rows):
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=_COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({key: (f"{value:.6g}" if isinstance(value, float) else value)
                             for key, value in row.items()})


def _pm(mean, std, digits=2):
    if not math.isfinite(mean):
        return "-"
    return f"{mean:.{digits}f} ± {std:.{digits}f}"


def _s_text(row):
    if not math.isfinite(row["s_db"]):
        return "-"
    text = _pm(row["s_db"], row["s_std_db"], 1)
    if row["s_limited"] > 0:
        text += f" (≥, {row['s_limited'] * 100:.0f} % noise-limited)"
    return text


def _write_markdown(path, config, rows, by_t, results, elapsed, workers, written):
    t_max = max(config.t_int_s)
    lines = ["# FLISS reproduction: results", "",
             f"Generated by `fliss reproduce` in {elapsed:.1f} s with {workers} worker(s): "
             f"{config.acquisitions} acquisitions per setting, T_int "
             f"{', '.join(f'{t * 1e3:g} ms' for t in config.t_int_s)}.", "",
             "## Parameters", "",
             "| parameter | value | source |", "| --- | --- | --- |",
             f"| clock | {format_frequency(config.clock_hz)} | Table 1 |",
             f"| nominal PRF | {format_frequency(config.clock_hz / config.period)} "
             f"(T = {config.period} cycles) | Table 1 |",
             f"| target distance | {DISTANCE_M} m (ToF {2 * DISTANCE_M / 299792458 * 1e9:.2f} ns)"
             f" | Table 1 |",
             f"| laser pulse FWHM (victim, aggressor) | {PULSE_FWHM_S * 1e9:g} ns | Table 1 |",
             f"| aggressor | {AGGRESSOR_OFFSET_S * 1e9:g} ns after the victim, at the victim's "
             f"{config.aggressor_prf} PRF | section 6 |",
             f"| victim echo | {config.signal:g} detections per pulse | model (TCSPC 5 % rule) |",
             f"| aggressor | {config.aggressor:g} detections per pulse | model (same emitter, "
             f"same target) |",
             f"| background (ambient + dark) | {config.background_hz:g} counts/s | model "
             f"(indoors) |",
             f"| SPAD dead time | {config.dead_time_s * 1e9:g} ns, non-paralysable | model |",
             f"| SPAD + TDC jitter | {config.jitter_fwhm_s * 1e12:g} ps FWHM | model |",
             f"| TDC | 50 ps LSB, 8192 codes, keeps the {config.keep} photon | Table 1, "
             f"Figure 6 |",
             f"| victim delay seed | {config.victim_seed} | model |", "",
             "## Paper and model side by side", "",
             "| quantity | paper | this model |", "| --- | --- | --- |"]
    reference = next(row for row in rows if row["experiment"].startswith("victim")
                     and row["t_int_ms"] == t_max * 1e3)
    lines.append(f"| victim ToF, T_int {t_max * 1e3:g} ms (Fig. 7) | {PAPER['victim_tof']} | "
                 f"{_pm(reference['tof_ns'], reference['tof_std_ns'], 3)} ns |")
    lines.append(f"| victim FWHM (Fig. 7) | {PAPER['victim_fwhm']} | "
                 f"{_pm(reference['fwhm_ns'], reference['fwhm_std_ns'], 3)} ns |")
    off = [result for result in results if result["job"].kind == "off"]
    if off:
        peaks = [peak for peak in off[0]["example_peaks"] if peak[0] != "victim"]
        victim_peak = [peak for peak in off[0]["example_peaks"] if peak[0] == "victim"]
        if peaks and victim_peak:
            delta = (max(peaks, key=lambda peak: peak[1])[0] - victim_peak[0][1]) * 1e9
            lines.append(f"| aggressor peak after the victim's (Fig. 8) | "
                         f"{PAPER['aggressor_delta']} | {delta:.2f} ns |")
        off_row = next(row for row in rows if row["experiment"].startswith("aggressor"))
        lines.append(f"| S with FLISS off (Fig. 8) | not given | "
                     f"{_s_text(off_row)} dB |")
    mseq = [row for row in rows if row["setting"].startswith("L =")]
    if mseq:
        best = max((row for row in mseq if row["t_int_ms"] == t_max * 1e3),
                   key=lambda row: row["s_db"], default=None)
        if best:
            lines.append(f"| S, complete m-sequences (Fig. 9) | {PAPER['s_mseq']} | best "
                         f"{_s_text(best)} dB at {best['setting']}, T_int {t_max * 1e3:g} ms |")
        dev_tof = max(abs(row["dev_tof_pct"]) for row in mseq)
        dev_fwhm = max(abs(row["dev_fwhm_pct"]) for row in mseq)
        lines.append(f"| ToF deviation (Fig. 11) | {PAPER['dev_tof']} | largest mean "
                     f"{dev_tof:.3f} % of {reference['tof_ns']:.2f} ns |")
        lines.append(f"| FWHM deviation (Fig. 11) | {PAPER['dev_fwhm']} | largest mean "
                     f"{dev_fwhm:.2f} % |")
        pv_text = ", ".join(f"{row['setting']}: {row['dev_pv_pct']:+.1f} %" for row in mseq
                            if row["t_int_ms"] == t_max * 1e3)
        lines.append(f"| Pv deviation (Fig. 11) | {PAPER['dev_pv']} | {pv_text} "
                     f"(T_int {t_max * 1e3:g} ms) |")
        prf_text = ", ".join(f"L={row['setting'][4:]}: {row['prf_eff_khz']:.1f} kHz"
                             for row in mseq if row["t_int_ms"] == t_max * 1e3)
        lines.append(f"| PRF_eff (Table 2) | 963.9, 919.5, 842.1, 720.7 kHz for L = 3-6 | "
                     f"{prf_text} |")
    masked = [row for row in rows if row["setting"].startswith("Wm")]
    if masked:
        best = max(masked, key=lambda row: row["s_db"])
        lines.append(f"| S, masked 32-bit LFSR (Fig. 12) | {PAPER['s_masked']} | best "
                     f"{_s_text(best)} dB at {best['setting']} |")
    lines += ["", "S is given as mean ± standard deviation over the acquisitions. \"≥\": in "
              "some acquisitions no aggressor peak rose above the detection threshold (5 noise "
              "deviations of the smoothed background, at least 1 count), so Pa was taken as "
              "that threshold and S is a lower bound set by the photon statistics.", "",
              "## All settings", "",
              "| experiment | setting | T_int (ms) | PRF_eff (kHz) | S (dB) | ToF (ns) | "
              "FWHM (ns) | Pv (counts) | ΔToF (%) | ΔFWHM (%) | ΔPv (%) | paper |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for row in rows:
        lines.append(
            f"| {row['experiment']} | {row['setting']} | {row['t_int_ms']:g} | "
            f"{row['prf_eff_khz']:.1f} | {_s_text(row)} | "
            f"{_pm(row['tof_ns'], row['tof_std_ns'], 3)} | "
            f"{_pm(row['fwhm_ns'], row['fwhm_std_ns'], 3)} | {_pm(row['pv'], row['pv_std'], 1)}"
            f" | {_pm(row['dev_tof_pct'], row['dev_tof_std_pct'], 3)} | "
            f"{_pm(row['dev_fwhm_pct'], row['dev_fwhm_std_pct'], 2)} | "
            f"{_pm(row['dev_pv_pct'], row['dev_pv_std_pct'], 1)} | {row['paper']} |")
    accounting = [result for result in results if result["job"].kind == "mseq"]
    if accounting:
        result = accounting[-1]
        lines += ["", f"## Photon accounting ({result['job'].name}, all acquisitions)", "",
                  "| source | " + " | ".join(COUNTERS) + " |",
                  "| --- |" + " --- |" * len(COUNTERS)]
        for source, counts in zip(result["sources"], result["counts"]):
            lines.append(f"| {source} | " + " | ".join(str(int(c)) for c in counts) + " |")
        lines += ["", "Every photon drawn is counted once: generated = outside + dead + "
                  "overwritten + recorded. \"outside\": it arrived outside every TDC window; "
                  "\"dead\": the SPAD was blind; \"overwritten\": the single-hit TDC kept another "
                  "photon of the same laser cycle."]
    lines += ["", "## Files", ""] + [f"* `{name}`" for name in written]
    with open(path, "w") as file:
        file.write("\n".join(lines) + "\n")


# Figures ---------------------------------------------------------------------------------------

def _figures(config, by_t, results, out_dir):
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    t_max = max(config.t_int_s)
    lsb_ns = 0.05
    written = []

    def save(figure, name):
        figure.tight_layout()
        figure.savefig(os.path.join(out_dir, name), dpi=110)
        plt.close(figure)
        written.append(name)

    def plot_histogram(axes, histogram, lo=0, hi=8192, **kwargs):
        codes = np.arange(lo, hi)
        axes.plot(codes * lsb_ns, histogram[lo:hi], drawstyle="steps-post", linewidth=0.7,
                  **kwargs)
        axes.set_xlabel("time from TDC start (ns)")
        axes.set_ylabel("counts per 50 ps code")

    # Figure 7: the victim alone
    reference = by_t[t_max]
    figure, axes = plt.subplots(figsize=(7, 4))
    plot_histogram(axes, reference["example"], 0, 2000)
    tof = analysis.mean_std(reference["tof"])[0] * 1e9
    fwhm = analysis.mean_std(reference["fwhm"])[0] * 1e9
    axes.set_title(f"Victim alone, FLISS off, T_int = {t_max * 1e3:g} ms: ToF {tof:.2f} ns, "
                   f"FWHM {fwhm:.2f} ns", fontsize=9)
    save(figure, "fig07_victim.png")

    by_kind = {}
    for result in results:
        by_kind.setdefault(result["job"].kind, []).append(result)

    # Figure 8: victim and aggressor, FLISS off
    if "off" in by_kind:
        figure, axes = plt.subplots(figsize=(7, 4))
        plot_histogram(axes, by_kind["off"][0]["example"], 0, 3000)
        axes.set_title(f"Victim and aggressor (offset 75 ns), FLISS off, "
                       f"T_int = {t_max * 1e3:g} ms", fontsize=9)
        save(figure, "fig08_aggressor.png")

    def s_plot(results_, setting_name, name, title, paper_point):
        figure, axes = plt.subplots(figsize=(6, 4))
        times = sorted({result["job"].t_int_s for result in results_})
        for t in times:
            chosen = sorted((r for r in results_ if r["job"].t_int_s == t),
                            key=lambda r: r["job"].setting)
            settings = [r["job"].setting for r in chosen]
            stats = [analysis.mean_std(r["s_db"]) for r in chosen]
            limited = [np.nanmean(np.asarray(r["limited"], dtype=float)) > 0.5 for r in chosen]
            line = axes.errorbar(settings, [s[0] for s in stats], yerr=[s[1] for s in stats],
                                 marker="o", capsize=3, label=f"T_int = {t * 1e3:g} ms")
            for x, (mean, _), flag in zip(settings, stats, limited):
                if flag:
                    axes.annotate("≥", (x, mean), textcoords="offset points", xytext=(4, 4),
                                  color=line[0].get_color())
        axes.plot(*paper_point, "r*", markersize=12, label="paper (highest reported)")
        axes.set_xticks(sorted({r["job"].setting for r in results_}))
        axes.set_xlabel(setting_name)
        axes.set_ylabel("suppression ratio S (dB)")
        axes.set_title(title, fontsize=9)
        axes.grid(alpha=0.3)
        axes.legend(fontsize=8)
        save(figure, name)

    if "mseq" in by_kind:
        s_plot(by_kind["mseq"], "LFSR length L (complete m-sequences)", "fig09_suppression_L.png",
               "Suppression ratio vs LFSR length (paper: Figure 9)", ([6], [35]))

        # Figure 10: histograms with FLISS on
        chosen = sorted((r for r in by_kind["mseq"] if r["job"].t_int_s == t_max),
                        key=lambda r: r["job"].setting)
        columns = 2
        rows_ = max(1, math.ceil(len(chosen) / columns))
        figure, grid = plt.subplots(rows_, columns, figsize=(10, 3 * rows_), squeeze=False)
        for axes, result in zip(grid.flat, chosen):
            plot_histogram(axes, result["example"])
            victim = [peak for peak in result["example_peaks"] if peak[0] == "victim"]
            if victim:
                _, _, pv, pa, limited = victim[0]
                level = analysis.background(result["example"])
                axes.axhline(level + pv, color="green", linewidth=0.8, label="victim peak")
                axes.axhline(level + pa, color="red", linewidth=0.8,
                             label="highest aggressor peak" + (" (≤ threshold)" if limited
                                                               else ""))
                axes.legend(fontsize=7)
            axes.set_title(f"L = {result['job'].setting}, T_int = {t_max * 1e3:g} ms",
                           fontsize=9)
        for axes in list(grid.flat)[len(chosen):]:
            axes.set_visible(False)
        save(figure, "fig10_histograms.png")

        # Figure 11: deviations from the reference
        figure, grid = plt.subplots(1, 3, figsize=(12, 3.8))
        for t in sorted({r["job"].t_int_s for r in by_kind["mseq"]}):
            chosen = sorted((r for r in by_kind["mseq"] if r["job"].t_int_s == t),
                            key=lambda r: r["job"].setting)
            ref = by_t[t]
            for axes, key, label in zip(grid, ("tof", "fwhm", "pv"),
                                        ("ToF", "FWHM", "peak height Pv")):
                reference_value = analysis.mean_std(ref[key])[0]
                stats = [analysis.mean_std(analysis.relative_deviation(r[key], reference_value)
                                           * 100) for r in chosen]
                axes.errorbar([r["job"].setting for r in chosen], [s[0] for s in stats],
                              yerr=[s[1] for s in stats], marker="o", capsize=3,
                              label=f"T_int = {t * 1e3:g} ms")
                axes.set_title(f"relative deviation of {label}", fontsize=9)
                axes.set_xlabel("LFSR length L")
                axes.set_xticks([r["job"].setting for r in chosen])
                axes.set_ylabel("%")
                axes.grid(alpha=0.3)
        grid[0].legend(fontsize=8)
        save(figure, "fig11_deviations.png")

    if "masked" in by_kind:
        s_plot(by_kind["masked"], "mask width Wm (32-bit LFSR)", "fig12_suppression_Wm.png",
               f"Suppression ratio vs mask width, T_int = {t_max * 1e3:g} ms "
               f"(paper: Figure 12)", ([6], [50]))
    return written


# Command line ----------------------------------------------------------------------------------

def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "reproduce", formatter_class=formatter,
        help="reproduce the paper's experiments (Figures 7-12) on the scene simulator",
        description="Runs the experiments of section 6 of the paper with the paper's "
                    "parameters on the photon-level scene simulator and writes PNG figures in "
                    "the spirit of Figures 7 to 12 and a results table (CSV and Markdown) next "
                    "to the paper's reported values. Photon rates, background, dead time and "
                    "jitter are not given in the paper; see docs/results.md.")
    parser.add_argument("--quick", action="store_true",
                        help="20 acquisitions per setting instead of 300 (under a minute)")
    parser.add_argument("--out", default="fliss-results", metavar="DIR",
                        help="output directory")
    parser.add_argument("--acquisitions", type=int, default=argparse.SUPPRESS, metavar="N",
                        help="acquisitions per setting: 300, or 20 with --quick")
    parser.add_argument("--t-int", nargs="+", default=["10ms", "30ms", "100ms"], metavar="T",
                        help="integration times; the longest is used for Figures 7, 8, 10, 12")
    parser.add_argument("--lengths", type=int, nargs="*", default=[3, 4, 5, 6], metavar="L",
                        help="LFSR lengths of the complete m-sequences (Figure 9)")
    parser.add_argument("--mask-widths", type=int, nargs="*", default=[1, 2, 3, 4, 5, 6],
                        metavar="W", help="mask widths on the 32-bit LFSR (Figure 12)")
    parser.add_argument("--signal", type=float, default=0.05, metavar="MEAN",
                        help="victim echo: mean detections per pulse")
    parser.add_argument("--aggressor", type=float, default=0.05, metavar="MEAN",
                        help="aggressor: mean detections per pulse at the victim's pixel")
    parser.add_argument("--background", default="100kHz", metavar="RATE",
                        help="ambient light plus dark counts")
    parser.add_argument("--dead-time", default="20ns", metavar="T", help="SPAD dead time")
    parser.add_argument("--jitter", default="100ps", metavar="T",
                        help="SPAD and TDC timing jitter, FWHM")
    parser.add_argument("--keep", choices=["first", "last"], default="last",
                        help="photon the single-hit TDC keeps per laser cycle")
    parser.add_argument("--aggressor-prf", choices=["effective", "nominal"], default="effective",
                        help="the aggressor's PRF: the victim's effective PRF (as in the paper) "
                             "or its nominal PRF")
    parser.add_argument("--seed", type=int, default=2019, help="seed of the photon statistics")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), metavar="N",
                        help="worker processes")
    parser.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    parser.set_defaults(run=run)


def _parse(function, text, option):
    """A positive quantity with units, or zero ("0", "0ns", "0 Hz")."""
    if re.fullmatch(r"\s*[-+]?0*\.?0*\s*[a-zµ]*\s*", str(text), flags=re.IGNORECASE) and \
            re.search(r"0", str(text)):
        return 0.0
    try:
        return float(function(text))
    except ValueError as error:
        raise UserError(f"{option}: {error}") from None


def run(args):
    acquisitions = getattr(args, "acquisitions", None)
    if acquisitions is None:
        acquisitions = 20 if args.quick else 300
    if args.jobs < 1:
        raise UserError(f"--jobs must be at least 1, not {args.jobs}")
    config = Config(
        acquisitions=acquisitions,
        t_int_s=tuple(sorted({_parse(parse_time, text, "--t-int") for text in args.t_int})),
        lengths=tuple(args.lengths), mask_widths=tuple(args.mask_widths),
        signal=args.signal, aggressor=args.aggressor,
        background_hz=_parse(parse_frequency, args.background, "--background"),
        dead_time_s=_parse(parse_time, args.dead_time, "--dead-time"),
        jitter_fwhm_s=_parse(parse_time, args.jitter, "--jitter"),
        keep=args.keep, aggressor_prf=args.aggressor_prf, seed=args.seed)
    try:
        config.check()
    except ValueError as error:
        raise UserError(str(error)) from None
    if not args.quiet:
        print(f"fliss reproduce: {config.acquisitions} acquisitions per setting, "
              f"{args.jobs} worker(s), writing to {args.out}", file=sys.stderr)
    rows = reproduce(config, args.out, workers=args.jobs, figures=not args.no_figures,
                     stream=None if args.quiet else sys.stderr)
    if not args.quiet:
        for row in rows:
            if math.isfinite(row["s_db"]):
                print(f"{row['setting']:>10}  T_int {row['t_int_ms']:>5g} ms  "
                      f"S = {_s_text(row)} dB")
        print(f"results: {os.path.join(args.out, 'results.md')}")
    return 0
