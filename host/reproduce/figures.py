"""The figures of ``fliss reproduce``: PNG files in the spirit of Figures 7 to 12 of the paper."""

import math
import os

import numpy as np

from .. import analysis
from ..plotting import legend_below, mark_peaks, styles


__all__ = ["figures"]


LSB_NS = 0.05


def figures(config, by_t, results, out_dir):
    """Draw the figures into ``out_dir``; return the names of the files written."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    t_max = max(config.t_int_s)
    written = []

    def save(figure, name):
        figure.savefig(os.path.join(out_dir, name), dpi=110)
        plt.close(figure)
        written.append(name)

    by_kind = {}
    for result in results:
        by_kind.setdefault(result["job"].kind, []).append(result)

    save(_victim_alone(plt, by_t[t_max], t_max), "fig07_victim.png")
    if "off" in by_kind:
        save(_with_aggressor(plt, by_kind["off"][0], t_max), "fig08_aggressor.png")
    if "mseq" in by_kind:
        save(_suppression(plt, by_kind["mseq"], "LFSR length L (complete m-sequences)",
                          "Suppression ratio vs LFSR length (paper: Figure 9)", ([6], [35])),
             "fig09_suppression_L.png")
        save(_histograms(plt, by_kind["mseq"], t_max), "fig10_histograms.png")
        save(_deviations(plt, by_kind["mseq"], by_t), "fig11_deviations.png")
    if "masked" in by_kind:
        save(_suppression(plt, by_kind["masked"], "mask width Wm (32-bit LFSR)",
                          f"Suppression ratio vs mask width, T_int = {t_max * 1e3:g} ms "
                          f"(paper: Figure 12)", ([6], [50])),
             "fig12_suppression_Wm.png")
    return written


def _plot_histogram(axes, histogram, lo=0, hi=8192, **kwargs):
    codes = np.arange(lo, hi)
    axes.plot(codes * LSB_NS, histogram[lo:hi], drawstyle="steps-post", linewidth=0.7, **kwargs)
    axes.set_xlabel("time from TDC start (ns)")
    axes.set_ylabel("counts per 50 ps code")


def _mark(axes, histogram, peaks):
    """Label the victim's peak and the highest aggressor peak: ``peaks`` as the results'
    ``example_peaks``, ``(ToF s, height)`` per aggressor peak, then the victim's."""
    level = analysis.background(histogram)
    victim = [peak for peak in peaks if peak[0] == "victim"]
    others = sorted((peak for peak in peaks if peak[0] != "victim"), key=lambda p: -p[1])
    marks = [(v[1] * 1e9, level + v[2], f"victim {v[1] * 1e9:.1f} ns", "tab:green")
             for v in victim[:1]]
    marks += [(position * 1e9, level + height, f"aggressor {position * 1e9:.1f} ns"
               + (f" (highest of {len(others)})" if len(others) > 1 else ""), "tab:red")
              for position, height in others[:1]]
    axes.set_ylim(top=axes.get_ylim()[1] * 1.15)
    mark_peaks(axes, marks)


def _victim_alone(plt, reference, t_max):
    """Figure 7: the victim alone."""
    figure, axes = plt.subplots(figsize=(7, 4), layout="constrained")
    _plot_histogram(axes, reference["example"], 0, 2000)
    tof = analysis.mean_std(reference["tof"])[0] * 1e9
    fwhm = analysis.mean_std(reference["fwhm"])[0] * 1e9
    axes.set_title(f"Victim alone, FLISS off, T_int = {t_max * 1e3:g} ms: ToF {tof:.2f} ns, "
                   f"FWHM {fwhm:.2f} ns", fontsize=9)
    return figure


def _with_aggressor(plt, result, t_max):
    """Figure 8: victim and aggressor, FLISS off."""
    figure, axes = plt.subplots(figsize=(7, 4), layout="constrained")
    _plot_histogram(axes, result["example"], 0, 3000)
    _mark(axes, result["example"], result["example_peaks"])
    axes.set_title(f"Victim and aggressor (offset 75 ns), FLISS off, "
                   f"T_int = {t_max * 1e3:g} ms", fontsize=9)
    return figure


def _suppression(plt, results, setting_name, title, paper_point):
    """Figures 9 and 12: S against the setting, a line per integration time."""
    figure, axes = plt.subplots(figsize=(6.5, 4.6), layout="constrained")
    times = sorted({result["job"].t_int_s for result in results})
    for index, (t, (colour, marker)) in enumerate(zip(times, styles(len(times)))):
        chosen = sorted((r for r in results if r["job"].t_int_s == t),
                        key=lambda r: r["job"].setting)
        settings = np.array([r["job"].setting for r in chosen], dtype=float)
        settings += 0.06 * (index - (len(times) - 1) / 2)     # apart from the other T_int
        stats = np.array([analysis.mean_std(r["s_db"]) for r in chosen])
        limited = np.array([np.nanmean(np.asarray(r["limited"], dtype=float)) > 0.5
                            for r in chosen], dtype=bool)
        axes.errorbar(settings, stats[:, 0], yerr=stats[:, 1], color=colour, capsize=3,
                      label=f"T_int = {t * 1e3:g} ms")
        axes.plot(settings[~limited], stats[~limited, 0], marker, color=colour)
        axes.plot(settings[limited], stats[limited, 0], marker, color=colour,
                  markerfacecolor="white")
    axes.plot(*paper_point, "r*", markersize=12, linestyle="none",
              label="paper (highest reported)")
    axes.plot([], [], "o", color="0.4", markerfacecolor="white",
              label="lower bound (no aggressor peak found)")
    axes.set_xticks(sorted({r["job"].setting for r in results}))
    axes.set_xlabel(setting_name)
    axes.set_ylabel("suppression ratio S (dB)")
    axes.set_title(title, fontsize=9)
    axes.grid(alpha=0.3)
    entries = sorted(zip(*axes.get_legend_handles_labels()),
                     key=lambda entry: not entry[1].startswith("T_int"))
    legend_below(figure, *zip(*entries), columns=2)
    return figure


def _histograms(plt, results, t_max):
    """Figure 10: histograms with FLISS on, a panel per LFSR length."""
    chosen = sorted((r for r in results if r["job"].t_int_s == t_max),
                    key=lambda r: r["job"].setting)
    columns = 2
    rows_ = max(1, math.ceil(len(chosen) / columns))
    figure, grid = plt.subplots(rows_, columns, figsize=(10, 1 + 3 * rows_), squeeze=False,
                                layout="constrained")
    bounds = False
    for axes, result in zip(grid.flat, chosen):
        _plot_histogram(axes, result["example"])
        victim = [peak for peak in result["example_peaks"] if peak[0] == "victim"]
        if victim:
            _, _, pv, pa, limited = victim[0]
            bounds |= bool(limited)
            level = analysis.background(result["example"])
            axes.axhline(level + pv, color="tab:green", linewidth=0.8)
            axes.axhline(level + pa, color="tab:red", linewidth=0.8,
                         linestyle=":" if limited else "-")
            _mark(axes, result["example"], result["example_peaks"])
        axes.set_title(f"L = {result['job'].setting}, T_int = {t_max * 1e3:g} ms", fontsize=9)
    for axes in list(grid.flat)[len(chosen):]:
        axes.set_visible(False)
    line = plt.Line2D
    legend_below(figure, [line([], [], color="tab:green"), line([], [], color="tab:red"),
                          line([], [], color="tab:red", linestyle=":")][:2 + bounds],
                 ["victim's peak Pv", "highest aggressor peak Pa",
                  "no aggressor peak: Pa at the detection threshold (S a lower bound)"
                  ][:2 + bounds])
    return figure


def _deviations(plt, results, by_t):
    """Figure 11: deviations of ToF, FWHM and Pv from the reference without an aggressor."""
    figure, grid = plt.subplots(1, 3, figsize=(12, 4.2), layout="constrained")
    times = sorted({r["job"].t_int_s for r in results})
    for index, (t, (colour, marker)) in enumerate(zip(times, styles(len(times)))):
        shift = 0.06 * (index - (len(times) - 1) / 2)     # apart from the other T_int
        chosen = sorted((r for r in results if r["job"].t_int_s == t),
                        key=lambda r: r["job"].setting)
        ref = by_t[t]
        for axes, key, label in zip(grid, ("tof", "fwhm", "pv"),
                                    ("ToF", "FWHM", "peak height Pv")):
            reference_value = analysis.mean_std(ref[key])[0]
            stats = [analysis.mean_std(analysis.relative_deviation(r[key], reference_value)
                                       * 100) for r in chosen]
            axes.errorbar([r["job"].setting + shift for r in chosen], [s[0] for s in stats],
                          yerr=[s[1] for s in stats], marker=marker, color=colour,
                          capsize=3, label=f"T_int = {t * 1e3:g} ms")
            axes.set_title(f"relative deviation of {label}", fontsize=9)
            axes.set_xlabel("LFSR length L")
            axes.set_xticks([r["job"].setting for r in chosen])
            axes.set_ylabel("%")
            axes.grid(alpha=0.3)
    legend_below(figure, *grid[0].get_legend_handles_labels())
    return figure
