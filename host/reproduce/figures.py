"""The figures of ``fliss reproduce``: PNG files in the spirit of Figures 7 to 12 of the paper."""

import math
import os

import numpy as np

from .. import analysis


__all__ = ["figures"]


def figures(config, by_t, results, out_dir):
    """Draw the figures into ``out_dir``; return the names of the files written."""
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
