"""The report of ``fliss reproduce``: result rows, CSV and Markdown tables beside the paper."""

import csv
import math

import numpy as np

from ...sim.scene import COUNTERS
from .. import analysis
from .experiments import AGGRESSOR_OFFSET_S, DISTANCE_M, PULSE_FWHM_S, victim_of
from ..units import format_frequency


__all__ = ["PAPER", "COLUMNS", "rows", "write_csv", "write_markdown", "s_text"]


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


def rows(config, by_t, results):
    """One result row (a dict with the keys of :data:`COLUMNS`) per setting."""
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
        victim = victim_of(config, job)
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


#: Columns of the CSV file, in order.
COLUMNS = ["experiment", "setting", "t_int_ms", "prf_eff_khz", "acquisitions", "s_db",
            "s_std_db", "s_limited", "tof_ns", "tof_std_ns", "fwhm_ns", "fwhm_std_ns", "pv",
            "pv_std", "dev_tof_pct", "dev_tof_std_pct", "dev_fwhm_pct", "dev_fwhm_std_pct",
            "dev_pv_pct", "dev_pv_std_pct", "paper"]


def write_csv(path, rows):
    """Write the result rows as CSV, floats with 6 significant digits."""
    with open(path, "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=COLUMNS)
        writer.writeheader()
        for row in rows:
            writer.writerow({key: (f"{value:.6g}" if isinstance(value, float) else value)
                             for key, value in row.items()})


def _pm(mean, std, digits=2):
    if not math.isfinite(mean):
        return "-"
    return f"{mean:.{digits}f} ± {std:.{digits}f}"


def s_text(row):
    """The suppression ratio of a row as text: mean ± deviation, marked when noise-limited."""
    if not math.isfinite(row["s_db"]):
        return "-"
    text = _pm(row["s_db"], row["s_std_db"], 1)
    if row["s_limited"] > 0:
        text += f" (≥, {row['s_limited'] * 100:.0f} % noise-limited)"
    return text


def write_markdown(path, config, rows, by_t, results, elapsed, workers, written):
    """Write the Markdown report: parameters, paper beside model, every setting, photons."""
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
                     f"{s_text(off_row)} dB |")
    mseq = [row for row in rows if row["setting"].startswith("L =")]
    if mseq:
        best = max((row for row in mseq if row["t_int_ms"] == t_max * 1e3),
                   key=lambda row: row["s_db"], default=None)
        if best:
            lines.append(f"| S, complete m-sequences (Fig. 9) | {PAPER['s_mseq']} | best "
                         f"{s_text(best)} dB at {best['setting']}, T_int {t_max * 1e3:g} ms |")
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
                     f"{s_text(best)} dB at {best['setting']} |")
    lines += ["", "S is given as mean ± standard deviation over the acquisitions. \"≥\": in "
              "some acquisitions no aggressor peak passed the significance test (background "
              "alone makes a peak in at most one histogram of a thousand: exact Poisson tails), "
              "so Pa was taken as the height of the least peak that would and S is a lower "
              "bound set by the photon statistics.", "",
              "## All settings", "",
              "| experiment | setting | T_int (ms) | PRF_eff (kHz) | S (dB) | ToF (ns) | "
              "FWHM (ns) | Pv (counts) | ΔToF (%) | ΔFWHM (%) | ΔPv (%) | paper |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for row in rows:
        lines.append(
            f"| {row['experiment']} | {row['setting']} | {row['t_int_ms']:g} | "
            f"{row['prf_eff_khz']:.1f} | {s_text(row)} | "
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
