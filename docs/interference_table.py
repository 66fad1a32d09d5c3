"""The table of docs/interference.md: the largest number of equal-power aggressors for which
P(wrong depth) per 10 ms frame stays below 1e-3, for each scheme, with :func:`evaluate`.

For each scheme and aggressor kind the number of aggressors doubles (1, 2, 4, ...) until a point
fails (``p_wrong_depth >= 1e-3``), then bisects between the last pass and the first fail. A
point passes with fewer than one wrong frame in a thousand: at most one of the 2000 ``--frames``
(upper 95 % Wilson bound 2.8e-3; give more frames for a tighter bound).

With ``--figures DIR`` it also draws, from the points it evaluated, P(wrong depth) and S against
the number of aggressors for each scheme and the detection curves at 8 aggressors (PNG files,
not kept in git).

Usage: ``python docs/interference_table.py [--frames N] [--max N] [--only NAME]
[--figures DIR]``
"""

import argparse
import json
import pathlib
import time

import numpy as np

from fliss.sim.studies.interference import evaluate


SCHEMES = {
    "off": {"scheme": "off"},
    "mseq L=6": {"scheme": "mseq", "length": 6},
    "masked Wm=6": {"scheme": "masked", "mask_width": 6},
    "grid (mseq L=6)": {"scheme": "mseq", "length": 6, "grid": True},
    "mseq L=6, 1/2 cycle": {"scheme": "mseq", "length": 6, "fine_step": 2},
    "mseq L=6, 1/4 cycle": {"scheme": "mseq", "length": 6, "fine_step": 4},
    "mseq L=6, 1/8 cycle": {"scheme": "mseq", "length": 6, "fine_step": 8},
    "mseq L=6, 1/16 cycle": {"scheme": "mseq", "length": 6, "fine_step": 16},
}

KINDS = {"own oscillators (±50 ppm)": "fliss", "locked worst case": "locked"}

LIMIT = 1e-3


def passes(point, frames, seed, log, record):
    start = time.perf_counter()
    result = evaluate(dict(point, frames=frames),
                      np.random.SeedSequence([seed, point["aggressors"]]))
    record.append((point["aggressors"], result))
    log(f"    N = {point['aggressors']:3d}: P(wrong) = {result['p_wrong_depth']:.4f} "
        f"[{result['p_wrong_depth_lo']:.4f}, {result['p_wrong_depth_hi']:.4f}], "
        f"P(ghost) = {result['p_ghost']:.3f}, S = {result['s_db'] or float('nan'):.1f} dB, "
        f"kept {result['signal_recorded']:.2f} ({time.perf_counter() - start:.0f} s)")
    return result["p_wrong_depth"] < LIMIT


def largest(base, frames, most, seed, log, record):
    """Largest N in 0 … most passing (most if all pass)."""
    good, bad, n = 0, None, 1
    while n <= most:
        if passes(dict(base, aggressors=n), frames, seed, log, record):
            good, n = n, 2 * n
        else:
            bad = n
            break
    if bad is None:
        return good, True
    while bad - good > 1:
        middle = (good + bad) // 2
        if passes(dict(base, aggressors=middle), frames, seed, log, record):
            good = middle
        else:
            bad = middle
    return good, False


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=2000, help="frames per point")
    parser.add_argument("--frames-per-run", type=int, default=2,
                        help="consecutive frames per independent draw of the aggressors")
    parser.add_argument("--max", type=int, default=64, help="most aggressors tried")
    parser.add_argument("--only", help="run only the schemes whose name contains this")
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--figures", type=pathlib.Path, help="draw the figures into DIR")
    args = parser.parse_args()
    rows, points = [], {}
    for name, scheme in SCHEMES.items():
        if args.only and args.only not in name:
            continue
        row = [name]
        for kind_name, kind in KINDS.items():
            print(f"{name}, {kind_name}:", flush=True)
            record = points.setdefault((name, kind_name), [])
            base = dict(scheme, aggressor_kind=kind, frames_per_run=args.frames_per_run)
            number, capped = largest(base, args.frames, args.max,
                                     args.seed, lambda line: print(line, flush=True), record)
            row.append(f"≥ {number}" if capped else str(number))
        rows.append(row)
    print()
    print("| scheme | " + " | ".join(KINDS) + " |")
    print("| --- | " + " | ".join("---" for _ in KINDS) + " |")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    if args.figures:
        draw(points, args.figures)


def draw(points, folder):
    """P(wrong depth) and S against N, and detection curves, as PNG files in ``folder``: a
    panel per aggressor kind, a line per scheme (colours and markers of their own), the legend
    below the panels."""
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib import pyplot
    from fliss.host.plotting import draw_proportion, legend_below, proportion_key, styles

    folder.mkdir(parents=True, exist_ok=True)
    lines = list(zip(SCHEMES, styles(len(SCHEMES))))
    positive = [result[key] for done in points.values() for _, result in done
                for key in ("p_wrong_depth", "p_wrong_depth_lo", "p_wrong_depth_hi")
                if result[key]]
    floor = 10 ** np.floor(np.log10(min(positive + [LIMIT]) / 2))
    for key, label, name in (("p_wrong_depth", "P(wrong depth) per frame", "p_wrong"),
                             ("s_db", "S (dB)", "s_db")):
        figure, axes = pyplot.subplots(1, len(KINDS), figsize=(11, 5), sharey=True,
                                       layout="constrained")
        for axis, kind in zip(axes, KINDS):
            for index, (scheme, (colour, marker)) in enumerate(lines):
                done = sorted(points.get((scheme, kind), []), key=lambda item: item[0])
                if not done:
                    continue
                # P side by side: the schemes' intervals at one N stay apart
                shift = 0.05 * (index - (len(lines) - 1) / 2) if key == "p_wrong_depth" else 0
                numbers = [number * 2 ** shift for number, _ in done]
                results = [result for _, result in done]
                if key == "p_wrong_depth":
                    draw_proportion(axis, numbers, [r["p_wrong_depth"] for r in results],
                                    [r["p_wrong_depth_lo"] for r in results],
                                    [r["p_wrong_depth_hi"] for r in results], colour=colour,
                                    marker=marker, floor=floor, label=scheme)
                else:
                    axis.plot(numbers, [np.nan if r[key] is None else r[key] for r in results],
                              marker=marker, color=colour, label=scheme)
            if key == "p_wrong_depth":
                axis.set_yscale("log")
                axis.set_ylim(floor, 1.0)
                axis.axhline(LIMIT, color="k", linestyle=":", label=f"limit {LIMIT:g}")
            axis.set_xscale("log", base=2)
            axis.set_xlabel("aggressors (equal power)")
            axis.set_title(kind)
            axis.grid(True, alpha=0.3)
        axes[0].set_ylabel(label)
        handles, labels = axes[0].get_legend_handles_labels()
        if key == "p_wrong_depth":
            extra, texts = proportion_key("no wrong depth in any frame: 95 % upper bound")
            handles, labels = handles + extra, labels + texts
        legend_below(figure, handles, labels)
        figure.savefig(folder / f"interference_{name}.png", dpi=120)
        pyplot.close(figure)
    figure, axes = pyplot.subplots(1, len(KINDS), figsize=(11, 5), sharey=True,
                                   layout="constrained")
    for axis, kind in zip(axes, KINDS):
        for index, (scheme, (colour, marker)) in enumerate(lines):
            done = [item for item in points.get((scheme, kind), []) if item[0] <= 8]
            if not done:
                continue
            number, result = max(done, key=lambda item: item[0])
            axis.plot(json.loads(result["curve_false_per_frame"]),
                      json.loads(result["curve_p_detect"]), marker=marker, color=colour,
                      markerfacecolor="none", markersize=8 - 4 * index / len(lines),
                      label=f"{scheme}, N={number}")
        axis.set_xscale("symlog", linthresh=1e-3)
        axis.set_xlabel("false targets per frame")
        axis.set_title(kind)
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=7, loc="upper left", bbox_to_anchor=(0, -0.15), ncol=2,
                    frameon=False)
    axes[0].set_ylabel("P(detect)")
    figure.savefig(folder / "interference_curves.png", dpi=120)
    pyplot.close(figure)


if __name__ == "__main__":
    main()
