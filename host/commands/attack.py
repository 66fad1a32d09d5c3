"""``fliss attack``: an attacker that predicts the victim's delays, against each delay source.

For each source the victim's pulses are generated, the attacker's observer records their
emission times (with jitter and misses), the attacker (:mod:`fliss.sim.studies.attacker`) searches for
a lock and fires; the scene simulator builds the victim's histograms with the attacker's pulses
as an aggressor at the ghost's distance, and the peak finder measures the ghost's
``S = 10 log10(Pv / P_ghost)``. See ``docs/security.md``.
"""

import argparse
import json
import math
import os
import secrets
import sys
import time
from pathlib import Path

import numpy as np

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.delay.settings import parse_hex
from ...sim.studies.attacker import Attacker, Observer
from ...sim.studies.generators import verify_pulses
from ...sim.studies.attack_scene import SOURCES, Victim, run as run_scene
from .. import analysis
from ..errors import UserError
from ..paths import check_output_path
from ..units import parse_time


__all__ = ["register", "run", "experiment", "theory"]


def _count(text):
    """A pulse count: ``50000``, ``1e6``."""
    try:
        value = float(text)
    except ValueError:
        raise UserError(f"Pulse count must be a whole number such as 50000 or 1e6, "
                        f"not {text!r}") from None
    if not math.isfinite(value) or value != int(value) or value < 1:
        raise UserError(f"Pulse count must be a positive whole number, not {text!r}")
    return int(value)


def _list(text, what, allowed=None):
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items:
        raise UserError(f"{what} must be a comma-separated list, not {text!r}")
    if allowed is not None:
        for item in items:
            if item not in allowed:
                raise UserError(f"{what}: {item!r} is not one of {', '.join(allowed)}")
        return items
    try:
        return [int(item, 0) for item in items]
    except ValueError:
        raise UserError(f"{what} must be comma-separated integers, not {text!r}") from None


def _hex80(text, flag, what):
    # A key: all 20 digits, or random; an IV: up to 20.
    key = what == "key"
    if key and text == "random":
        return int.from_bytes(secrets.token_bytes(10), "big")
    try:
        return parse_hex(text, what, exact=key, alternative="random" if key else None)
    except ValueError as error:
        raise UserError(f"{flag} {text}: {error}") from None


def theory(victim):
    """Pulses observed until lock in theory, known and unknown taps (``None`` where the source
    is not a linear register): in interval mode one pulse whose delay cannot be read (no
    interval before it; in grid mode the phase search reads it), then the pulses that determine
    the register (1 for ``mseq``, ``ceil(32 / Wm)`` for ``masked``; ``2 L`` bits for
    Berlekamp-Massey), then the checked ones."""
    first = 0 if victim.grid else 1
    if victim.mode == "mseq":
        length = victim.length
        return (first + 1 + verify_pulses(length, 48),
                first + 2 * length + verify_pulses(length, 48))
    if victim.mode == "masked":
        width = victim.mask_width
        return (first + -(-32 // width) + verify_pulses(width, 48),
                first + 2 * 32 + verify_pulses(width, 48))
    return None, None


def _register_seed(seed, length):
    """The register state a seed loads as (its low bits, 1 if they are all zero)."""
    if not 2 <= length <= 32:
        raise UserError(f"--lengths: L must be from 2 to 32, not {length}")
    return (seed & ((1 << length) - 1)) or 1


def _victims(args):
    victims = []
    for source in args.sources:
        if source == "mseq":
            victims += [Victim("mseq", length=length, seed=_register_seed(args.seed, length),
                               period=args.period,
                               grid=args.grid) for length in args.lengths]
        elif source == "masked":
            victims += [Victim("masked", mask_width=width, seed=args.seed, period=args.period,
                               grid=args.grid) for width in args.mask_widths]
        elif source in ("keyed", "random"):
            victims.append(Victim(source, mask_width=args.keyed_width, seed=args.seed,
                                  key=args.key, iv=args.iv, period=args.period, grid=args.grid))
        else:
            victims.append(Victim("off", period=args.period, grid=args.grid))
    return victims


def _median(values):
    """Median of the finite values, or ``None`` (JSON has no NaN)."""
    values = values[np.isfinite(values)]
    return float(np.median(values)) if len(values) else None


def _measure(histograms):
    """S of the ghost in each histogram, whether it is a lower bound, and whether the peak
    finder reports the ghost as a target."""
    s_db, limited, reported = [], [], []
    for histogram in histograms.histograms:
        try:
            result = analysis.suppression(histogram, histograms.victim_s, [histograms.ghost_s])
        except ValueError:
            s_db.append(math.nan)
            limited.append(False)
            reported.append(False)
            continue
        s_db.append(result.s_db)
        limited.append(result.limited)
        reported.append(not result.limited)
    return np.array(s_db), np.array(limited), np.array(reported)


def experiment(victims, *, pulses, scene_pulses, acquisition_pulses, observer, ghost_m,
               unknown_taps=True, clock_hz=DEFAULT_CLOCK_HZ, seed=1, progress=None):
    """One row per victim: the attack, its lock, and the ghost it makes."""
    rows = []
    attackers = {}
    for index, victim in enumerate(victims):
        key = (victim.period, victim.grid)
        if key not in attackers:
            common = dict(grid=victim.grid, clock_hz=clock_hz, jitter_s=observer.jitter_s)
            attackers[key] = (Attacker(victim.period, **common),
                              Attacker(victim.period, known_taps=False, **common)
                              if unknown_taps else None)
        attacker, blind = attackers[key]
        started = time.monotonic()
        scene_count = min(pulses, scene_pulses)
        starts = victim.start_cycles(pulses + 1, start=100)
        times, seen = observer.observe(starts[:pulses])
        result = attacker.attack(times)
        blind_result = blind.attack(times[:min(len(times), 4096)]) if blind else None
        edges = result.edges
        lock_s = None if result.locked_after is None else \
            float((np.rint(times[result.locked_after - 1] * clock_hz) - starts[0]) / clock_hz)
        histograms = run_scene(victim, starts[:scene_count + 1], edges, acquisition_pulses,
                               ghost_m=ghost_m, clock_hz=clock_hz, seed=seed + index)
        s_db, limited, reported = _measure(histograms)
        after = histograms.end_s >= (lock_s if lock_s is not None else 0.0)
        known, unknown = theory(victim)
        rows.append({
            "mode": victim.mode,
            "length": victim.length,
            "mask_width": victim.mask_width,
            "label": victim.label,
            "observed_pulses": int(len(times)),
            "locked_after_pulses": result.locked_after,
            "locked_model": result.model,
            "locks": len(result.locks),
            "lock_time_s": lock_s,
            "theory_known_taps": known,
            "locked_after_pulses_unknown_taps": None if blind_result is None else
            blind_result.locked_after,
            "theory_unknown_taps": unknown,
            "ghost_s_db": _median(s_db[after]),
            "ghost_s_lower_bound": bool(limited[after].all()) if after.any() else None,
            "ghost_reported_fraction": float(reported[after].mean()) if after.any() else None,
            "s_db": [None if not math.isfinite(value) else round(float(value), 2)
                     for value in s_db],
            "s_db_lower_bound": [bool(value) for value in limited],
            "time_s": [float(value) for value in histograms.end_s],
            "seconds": round(time.monotonic() - started, 2),
        })
        if progress is not None:
            progress(rows[-1])
    return rows


#: Colour map of each delay source in the figure: a hue per source, shades for its L or Wm.
_FAMILY_COLOURS = {"off": "Greys", "mseq": "Blues", "masked": "Oranges", "keyed": "Greens",
                   "random": "Purples"}


#: Sources drawn in one panel of S at most; more get a panel per family.
_ONE_PANEL = 6


def _family(row):
    return "keyed, random" if row["mode"] in ("keyed", "random") else row["mode"]


def _colours(rows):
    """A colour per row, none repeated: the hue of its source, a shade per variant."""
    from matplotlib import colormaps
    colours = []
    for row in rows:
        same = [other for other in rows if other["mode"] == row["mode"]]
        shade = 0.75 if len(same) == 1 else 0.45 + 0.5 * same.index(row) / (len(same) - 1)
        colours.append(colormaps[_FAMILY_COLOURS.get(row["mode"], "Greys")](shade))
    return colours


def _figure(rows, path):
    """Left: pulses observed until the attacker locks, per source, with the theory. Right:
    the ghost's S against time, one panel per source family (one for all of up to
    :data:`_ONE_PANEL` sources), a legend beside each."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch
    from ..plotting import legend_below

    colours = _colours(rows)
    family = _family if len(rows) > _ONE_PANEL else (lambda row: "")
    families = list(dict.fromkeys(family(row) for row in rows))
    figure = plt.figure(figsize=(13, 1.8 + 2.2 * max(len(families), 2)), layout="constrained")
    grid = figure.add_gridspec(len(families), 2, width_ratios=[1, 1.5])
    left = figure.add_subplot(grid[:, 0])
    right = [figure.add_subplot(grid[index, 1]) for index in range(len(families))]
    for axis in right[1:]:
        axis.sharex(right[0])
        axis.sharey(right[0])

    # Pulses until lock
    labels = [row["label"] for row in rows]
    for position, (row, colour) in enumerate(zip(rows, colours)):
        locked = row["locked_after_pulses"]
        if locked:
            left.barh(position, locked, color=colour, edgecolor="0.3", linewidth=0.5)
            text = f" {locked}"
        else:
            left.barh(position, row["observed_pulses"], color="none", edgecolor="0.5",
                      hatch="//", linewidth=0.5)
            text = f" not locked after {row['observed_pulses']}"
        left.text(locked or row["observed_pulses"], position, text, va="center", fontsize=8)
        if row["theory_known_taps"] is not None:
            left.plot([row["theory_known_taps"]], [position], "|", color="k", markersize=14,
                      markeredgewidth=2)
    left.set_yticks(range(len(rows)), labels)
    left.set_xscale("log")
    left.set_xlim(0.7, max(row["observed_pulses"] for row in rows) * 20)
    left.set_xlabel("victim pulses observed until the attacker locks")
    left.invert_yaxis()

    # The ghost's S against time
    for axis, name in zip(right, families):
        for row, colour in zip(rows, colours):
            if family(row) != name:
                continue
            times = np.array(row["time_s"]) * 1e3
            values = np.array([math.nan if v is None else v for v in row["s_db"]])
            bound = np.array(row["s_db_lower_bound"], dtype=bool)
            style = "-" if row["locked_after_pulses"] else "--"
            axis.plot(times, values, style, color=colour, label=row["label"])
            axis.plot(times[~bound], values[~bound], "o", color=colour, markersize=3)
            axis.plot(times[bound], values[bound], "^", color=colour, markersize=5,
                      markerfacecolor="none")
            if row["lock_time_s"] is not None:
                axis.axvline(row["lock_time_s"] * 1e3, color=colour, linestyle=":",
                             linewidth=1.2)
        axis.axhline(0, color="0.5", linewidth=0.6)
        axis.set_xscale("log")
        axis.set_ylabel("ghost S (dB)")
        axis.set_title(name, fontsize="small", loc="left")
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        if axis is not right[-1]:
            axis.tick_params(labelbottom=False)
    right[-1].set_xlabel("time since the attack started (ms)")

    legend_below(figure, [
        Line2D([], [], color="k", marker="|", linestyle="none", markersize=12,
               markeredgewidth=2),
        Patch(facecolor="none", edgecolor="0.5", hatch="//"),
        Line2D([], [], color="0.3"), Line2D([], [], color="0.3", linestyle="--"),
        Line2D([], [], color="0.3", marker="^", markerfacecolor="none", linestyle="none"),
        Line2D([], [], color="0.3", linestyle=":")], [
        "theory (known taps)", "never locked: pulses observed", "S after a lock",
        "S, never locked", "lower bound: no ghost peak found", "lock",
        ], columns=3)
    figure.suptitle("An attacker that predicts the delays: how soon it locks, and the ghost's "
                    "S = 10 log10(Pv / P_ghost); 0 dB: the ghost as tall as the target",
                    fontsize="small")
    figure.savefig(path, dpi=120, format=_image_format(path))
    plt.close(figure)


def _image_format(path):
    # The file's ending, or PNG without one (written under the name given, which matplotlib
    # would otherwise give a .png of its own).
    return os.path.splitext(path)[1].lower().lstrip(".") or "png"


def _check_image_format(path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    formats = FigureCanvasAgg.get_supported_filetypes()
    if _image_format(path) not in formats:
        raise UserError(f"--figure: cannot write a .{_image_format(path)} image; use one of "
                        f"{', '.join('.' + name for name in sorted(formats))}")


def _table(rows):
    header = (f"{'source':<16} {'observed':>9} {'locked after':>12} {'theory':>7} "
              f"{'unknown taps':>12} {'theory':>7} {'ghost S (dB)':>13} {'reported':>9}  model")
    lines = [header, "-" * len(header)]
    for row in rows:
        def cell(value, width):
            return f"{'-' if value is None else value:>{width}}"
        s_db = row["ghost_s_db"]
        s_text = "-" if s_db is None else \
            f"{'>=' if row['ghost_s_lower_bound'] else ''}{s_db:.1f}"
        reported = row["ghost_reported_fraction"]
        lines.append(
            f"{row['label']:<16} {row['observed_pulses']:>9} "
            f"{cell(row['locked_after_pulses'] or 'never', 12)} "
            f"{cell(row['theory_known_taps'], 7)} "
            f"{cell(row['locked_after_pulses_unknown_taps'], 12)} "
            f"{cell(row['theory_unknown_taps'], 7)} {s_text:>13} "
            f"{cell(None if reported is None else f'{100 * reported:.0f}%', 9)}  "
            f"{row['locked_model'] or ''}")
    return "\n".join(lines)


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "attack", formatter_class=formatter,
        help="run an attacker that predicts the delays against each delay source",
        description="An attacker watches the victim's laser (emission times with jitter and "
                    "missed pulses), recovers the delays and the generator (register state by "
                    "GF(2) linear algebra with known taps, Berlekamp-Massey with unknown ones), "
                    "locks when its predictions hold, then fires so that a ghost appears at a "
                    "chosen distance. The scene simulator measures the ghost with the peak "
                    "finder. Prints a table, writes a figure. See docs/security.md.")
    parser.add_argument("--sources", default=",".join(SOURCES), metavar="LIST",
                        help=f"victim delay sources, comma-separated, from {', '.join(SOURCES)}")
    parser.add_argument("--lengths", default="4,6,10,16", metavar="LIST",
                        help="register lengths L of the mseq victims")
    parser.add_argument("--mask-widths", default="1,3,6,10", metavar="LIST",
                        help="mask widths Wm of the masked victims")
    parser.add_argument("--keyed-width", type=int, default=6, metavar="WM",
                        help="Wm of the keyed and random victims")
    parser.add_argument("--key", default="random", metavar="HEX",
                        help="keyed victim's 80-bit key (20 hex digits) or 'random' (never "
                             "printed)")
    parser.add_argument("--iv", default="0", metavar="HEX", help="keyed victim's 80-bit IV")
    parser.add_argument("--seed", type=lambda text: int(text, 0), default=0xACE1,
                        help="register seed of mseq/masked, generator seed of random and of "
                             "the photons")
    parser.add_argument("--period", type=int, default=80, metavar="CYCLES",
                        help="victim's nominal period T in clock cycles (80: 1 MHz at 80 MHz)")
    parser.add_argument("--grid", action="store_true", help="victim in grid scheduler mode")
    parser.add_argument("--pulses", default="50000", metavar="N",
                        help="victim pulses the attacker observes (1e6 for the keyed claim)")
    parser.add_argument("--scene-pulses", default="50000", metavar="N",
                        help="victim pulses simulated in the scene (at most --pulses)")
    parser.add_argument("--acquisition-pulses", default="5000", metavar="N",
                        help="victim pulses in each histogram")
    parser.add_argument("--jitter", default="100ps", metavar="TIME",
                        help="RMS jitter of the attacker's emission times")
    parser.add_argument("--missed", type=float, default=0.0, metavar="FRACTION",
                        help="fraction of the victim's pulses the attacker misses (0 to <1)")
    parser.add_argument("--ghost-m", type=float, default=10.0, metavar="M",
                        help="distance of the ghost target the attacker creates")
    parser.add_argument("--no-unknown-taps", action="store_true",
                        help="skip the second attacker that does not use the polynomial table")
    parser.add_argument("--table", default=argparse.SUPPRESS, metavar="PATH",
                        help="table output ('-': none; attack.txt if not given, except with "
                             "--json)")
    parser.add_argument("--figure", default=argparse.SUPPRESS, metavar="PATH",
                        help="figure output ('-': none; attack.png if not given, except with "
                             "--json)")
    parser.add_argument("--json", action="store_true",
                        help="print the table as JSON, and write only the outputs asked for "
                             "(--table, --figure)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing file named by --table or --figure (the "
                             "default attack.txt and attack.png are replaced anyway)")
    parser.set_defaults(run=run)


#: The options that only some sources read, and those sources.
_SOURCE_OPTIONS = {"lengths": ("--lengths", ("mseq",)),
                   "mask_widths": ("--mask-widths", ("masked",)),
                   "keyed_width": ("--keyed-width", ("keyed", "random")),
                   "key": ("--key", ("keyed",)), "iv": ("--iv", ("keyed",))}


def _check_options_apply(args):
    # An option of a source not in --sources would be ignored: refused instead.
    given = getattr(args, "given", frozenset())
    for name, (option, sources) in _SOURCE_OPTIONS.items():
        if name in given and not set(sources) & set(args.sources):
            raise UserError(f"{option} is an option of the {' and '.join(sources)} "
                            f"victim{'s' if len(sources) > 1 else ''}, not in --sources "
                            f"{','.join(args.sources)}")


def _arguments(args):
    args.sources = _list(args.sources, "--sources", SOURCES)
    args.lengths = _list(args.lengths, "--lengths")
    args.mask_widths = _list(args.mask_widths, "--mask-widths")
    args.pulses = _count(args.pulses)
    args.scene_pulses = _count(args.scene_pulses)
    args.acquisition_pulses = _count(args.acquisition_pulses)
    if args.pulses < 2:
        raise UserError("--pulses must be at least 2")
    if args.acquisition_pulses > min(args.pulses, args.scene_pulses):
        raise UserError(f"--acquisition-pulses ({args.acquisition_pulses}) must not exceed "
                        f"the simulated pulses ({min(args.pulses, args.scene_pulses)})")
    if not math.isfinite(args.ghost_m) or not 0 < args.ghost_m <= 60:
        raise UserError(f"--ghost-m must be from 0 to 60 m (inside the TDC range), "
                        f"not {args.ghost_m:g}")
    if not math.isfinite(args.missed) or not 0 <= args.missed < 1:
        raise UserError(f"--missed must be a fraction from 0 to below 1, not {args.missed:g}")
    try:
        args.jitter_s = parse_time(args.jitter, zero=True)
    except ValueError as error:
        raise UserError(f"--jitter {args.jitter}: {error}") from None
    _check_options_apply(args)
    args.key = _hex80(args.key, "--key", "key")
    args.iv = _hex80(args.iv, "--iv", "IV")
    try:
        return _victims(args)
    except ValueError as error:
        raise UserError(str(error)) from None


def run(args):
    victims = _arguments(args)
    # Files the command writes unasked, except with --json (whose output is the table).
    for name, default in (("table", "attack.txt"), ("figure", "attack.png")):
        setattr(args, name, getattr(args, name, "-" if args.json else default))
    # Outputs are checked before minutes of work; they are replaced as plot's are.
    # (the default names are replaced, run after run; a file named by the user only with
    # --overwrite)
    given = getattr(args, "given", frozenset())
    if args.table != "-":
        check_output_path(args.table, overwrite=None if "table" not in given else args.overwrite,
                          flag="--table")
    if args.figure != "-":
        check_output_path(args.figure,
                          overwrite=None if "figure" not in given else args.overwrite,
                          flag="--figure")
        _check_image_format(args.figure)
    observer = Observer(jitter_s=args.jitter_s, missed=args.missed, seed=args.seed)

    def progress(row):
        if not args.json:
            locked = row["locked_after_pulses"]
            print(f"  {row['label']:<16} {'locked after ' + str(locked) if locked else 'not locked'}"
                  f" ({row['seconds']:.1f} s)", file=sys.stderr, flush=True)

    rows = experiment(victims, pulses=args.pulses, scene_pulses=args.scene_pulses,
                      acquisition_pulses=args.acquisition_pulses, observer=observer,
                      ghost_m=args.ghost_m, unknown_taps=not args.no_unknown_taps,
                      seed=args.seed, progress=progress)
    table = _table(rows)
    if args.table != "-":
        Path(args.table).write_text(table + "\n")
    if args.figure != "-":
        _figure(rows, args.figure)
    if args.json:
        json.dump(rows, sys.stdout, indent=1)
        print()
    else:
        print(table)
        outputs = [path for path in (args.table, args.figure) if path != "-"]
        if outputs:
            print("wrote " + ", ".join(os.fspath(path) for path in outputs))
    return 0
