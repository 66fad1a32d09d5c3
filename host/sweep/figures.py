"""Figures of ``fliss sweep``, drawn from the table's rows (PNG, matplotlib).

Each figure needs some columns and a parameter that varies; when the sweep lacks them the figure
is skipped and :func:`figures` says why.

Each figure compares the values of one varied parameter, the *compared* one: ``scheme`` when the
points vary it, else ``aggressor_kind``, else the first varied parameter off the x axis. Each
value is one line, in a colour and marker of its own (:func:`fliss.host.plotting.styles`), in
every panel; a parameter that moves with the compared one (a ``zip`` group) joins its labels.
Every other parameter that varies among the points drawn makes the panels, one per combination
of values (at most :data:`MAX_PANELS`), titled with them. The legend sits below the panels.
"""

import json
import math
import os

from ..plotting import draw_proportion, legend_below, proportion_key, styles


__all__ = ["figures", "POWER_COLUMNS", "CURVE_COLUMNS", "COMPARED", "FRAME_T_INT_S",
           "MAX_PANELS"]


#: Parameter giving the aggressors' power, first found wins.
POWER_COLUMNS = ("aggressor_power_db", "aggressor_power", "power_db", "power")
#: The frame length of the P(wrong depth) figure: 10 ms.
FRAME_T_INT_S = 10e-3
#: Parameters compared by the lines of a figure, first varied wins.
COMPARED = ("scheme", "aggressor_kind")
#: Panels of a figure at most; the note of a figure with more says how many were left out.
MAX_PANELS = 24

#: Detection curve of a point: JSON lists of equal length, P(detect) and false targets per frame.
CURVE_COLUMNS = ("curve_p_detect", "curve_false_per_frame")


def _first(columns, names):
    return next((name for name in names if name in columns), None)


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and \
        value is not None and math.isfinite(value)


def _text(value):
    return f"{value:g}" if isinstance(value, float) else str(value)


def _values(rows, name):
    """The values ``name`` takes in ``rows``, in the order they first appear."""
    return list(dict.fromkeys(row.get(name) for row in rows))


class _Layout:
    """Which rows make which line and which panel.

    ``lines``: ``[(key, label)]``, one per value of the compared parameter; ``panels``:
    ``[(key, title)]``, one per combination of the facet parameters; ``line_of(row)`` and
    ``panel_of(row)`` give a row's keys."""

    def __init__(self, rows, varied, x):
        names = [name for name in varied if name != x and len(_values(rows, name)) > 1]
        compared = _first(names, COMPARED) or (names[0] if names else None)
        values = _values(rows, compared) if compared else [None]
        tied = [name for name in names if name != compared and all(
            len(_values([row for row in rows if row.get(compared) == value], name)) == 1
            for value in values)]
        self.facets = [name for name in names if name != compared and name not in tied]

        def line_label(value):
            if compared is None:
                return "all points"
            row = next(row for row in rows if row.get(compared) == value)
            return ", ".join(f"{name}={_text(row.get(name))}" for name in [compared] + tied)
        self.lines = [(value, line_label(value)) for value in values]
        self.line_of = (lambda row: row.get(compared)) if compared else (lambda row: None)
        self.panel_of = lambda row: tuple(row.get(name) for name in self.facets)
        keys = list(dict.fromkeys(self.panel_of(row) for row in rows))
        self.panels = [(key, ", ".join(f"{name}={_text(value)}"
                                        for name, value in zip(self.facets, key)))
                       for key in keys]
        last = len(_values(rows, self.facets[-1])) if self.facets else 1
        count = min(len(self.panels), MAX_PANELS)
        self.columns = last if len(self.facets) > 1 and last <= 5 else \
            math.ceil(count / math.ceil(count / 3))
        self.rows = math.ceil(count / self.columns)

    def note(self, what):
        if len(self.panels) <= MAX_PANELS:
            return None
        return f"{what}: the first {MAX_PANELS} of {len(self.panels)} panels drawn (one per " \
               f"{', '.join(self.facets)})"

    def figure(self, plt, xlabel, ylabel):
        """The figure and its panels, ``[(axes, panel key)]``, titled, the axes labelled on
        the outer panels; spare axes hidden."""
        figure, grid = plt.subplots(self.rows, self.columns, squeeze=False, sharex=True,
                                    sharey=True, layout="constrained",
                                    figsize=(0.6 + 3.6 * self.columns, 1.3 + 2.8 * self.rows))
        axes = list(grid.flat)
        panels = self.panels[:MAX_PANELS]
        for index, (axis, (_, title)) in enumerate(zip(axes, panels)):
            axis.set_title(title, fontsize="small")
            axis.grid(True, alpha=0.3)
            if index + self.columns >= len(panels):      # nothing drawn below it
                axis.xaxis.set_tick_params(labelbottom=True)
                axis.set_xlabel(xlabel)
            if index % self.columns == 0:
                axis.set_ylabel(ylabel)
        for axis in axes[len(panels):]:
            axis.set_visible(False)
        return figure, [(axis, key) for axis, (key, _) in zip(axes, panels)]

    def styled(self):
        """``[(line key, label, colour, marker)]``."""
        return [(key, label, colour, marker) for (key, label), (colour, marker)
                in zip(self.lines, styles(len(self.lines)))]


def _save(figure, out_dir, name):
    figure.savefig(os.path.join(out_dir, name), dpi=120)
    import matplotlib.pyplot as plt
    plt.close(figure)
    return name


def _x_axis(axes, values, name):
    """A log axis for a positive quantity spanning a factor of 4 or more, ticks at the values."""
    values = sorted({value for value in values if _number(value)})
    if values and values[0] > 0 and values[-1] >= 4 * values[0] and not name.endswith("_db"):
        axes.set_xscale("log")
        axes.set_xticks(values, [_text(value) for value in values])
        axes.minorticks_off()
        return True
    return False


def _dodged(x, index, count, log, spacing):
    """``x`` moved sideways for line ``index`` of ``count``, so equal points stay apart (all
    of them within 0.4 of an octave, or of the spacing of the values)."""
    shift = (index - (count - 1) / 2) * min(0.06, 0.4 / count)
    return x * 2 ** shift if log else x + spacing * shift


def _at_frame(rows):
    if "t_int_s" not in rows[0]:
        return rows
    return [row for row in rows if _number(row["t_int_s"]) and
            math.isclose(row["t_int_s"], FRAME_T_INT_S, rel_tol=1e-6)]


def _wrong_depth(rows, varied, out_dir, plt):
    if "aggressors" not in varied:
        return None, "P(wrong depth) figure skipped: the sweep does not vary 'aggressors'"
    if "p_wrong_depth" not in rows[0]:
        return None, "P(wrong depth) figure skipped: the table has no 'p_wrong_depth'"
    at = [row for row in _at_frame(rows) if _number(row["p_wrong_depth"])]
    if not at:
        return None, "P(wrong depth) figure skipped: no point has t_int_s = 0.01 (10 ms)"
    bounds = "p_wrong_depth_lo" in at[0] and "p_wrong_depth_hi" in at[0]
    positive = [row[name] for row in at
                for name in ("p_wrong_depth", "p_wrong_depth_lo", "p_wrong_depth_hi")
                if _number(row.get(name)) and row[name] > 0]
    floor = 10 ** math.floor(math.log10(min(positive) / 2)) if positive else 1e-3
    layout = _Layout(at, varied, "aggressors")
    figure, panels = layout.figure(plt, "aggressors", "P(wrong depth) per 10 ms frame")
    xs = sorted({row["aggressors"] for row in at})
    spacing = min((b - a for a, b in zip(xs, xs[1:])), default=1)
    lines = layout.styled()
    for axes, key in panels:
        log = _x_axis(axes, xs, "aggressors")
        for index, (line, label, colour, marker) in enumerate(lines):
            group = sorted((row for row in at if layout.panel_of(row) == key and
                            layout.line_of(row) == line), key=lambda row: row["aggressors"])
            x = [_dodged(row["aggressors"], index, len(lines), log, spacing) for row in group]
            p = [row["p_wrong_depth"] for row in group]
            if bounds:
                draw_proportion(axes, x, p, [row["p_wrong_depth_lo"] or 0.0 for row in group],
                                [row["p_wrong_depth_hi"] or row["p_wrong_depth"]
                                 for row in group], colour=colour, marker=marker, floor=floor,
                                label=label)
            else:
                axes.plot(x, [value if value > 0 else math.nan for value in p], marker=marker,
                          color=colour, markersize=5, label=label)
        axes.set_yscale("log")
        axes.set_ylim(floor, 1.0)
    handles = [plt.Line2D([], [], color=colour, marker=marker) for _, _, colour, marker in lines]
    labels = [label for _, label, _, _ in lines]
    if bounds:
        extra, texts = proportion_key("no wrong depth in any frame: 95 % upper bound")
        handles, labels = handles + extra, labels + texts
    legend_below(figure, handles, labels)
    return _save(figure, out_dir, "p_wrong_depth_vs_aggressors.png"), \
        layout.note("P(wrong depth) figure")


def _curve(row):
    """``[(false per frame, P(detect)), ...]`` of a row, sorted, or empty."""
    try:
        ys, xs = (json.loads(row[name]) for name in CURVE_COLUMNS)
    except (TypeError, ValueError):
        return []
    return sorted((x, y) for x, y in zip(xs, ys) if _number(x) and _number(y))


def _detection_curves(rows, varied, out_dir, plt):
    if not all(name in rows[0] for name in CURVE_COLUMNS):
        return None, f"detection curves skipped: the table has no {' and '.join(CURVE_COLUMNS)}"
    at = _at_frame(rows) or rows
    curves = [(row, _curve(row)) for row in at]
    positive = [x for _, pairs in curves for x, _ in pairs if x > 0]
    linear = 10 ** math.floor(math.log10(min(positive))) if positive else 1e-3
    layout = _Layout(at, varied, None)
    figure, panels = layout.figure(plt, "false targets per frame", "P(detect)")
    lines = layout.styled()
    for axes, key in panels:
        for index, (line, label, colour, marker) in enumerate(lines):
            for row, pairs in curves:
                if pairs and layout.panel_of(row) == key and layout.line_of(row) == line:
                    # earlier lines drawn larger, so a later one on top leaves them visible
                    axes.plot([p[0] for p in pairs], [p[1] for p in pairs], marker=marker,
                              color=colour, markersize=7 - 4 * index / max(len(lines), 2),
                              markerfacecolor="none", linewidth=1, label=label)
        axes.set_xscale("symlog", linthresh=linear)
        axes.set_ylim(-0.03, 1.05)
    frame = " per 10 ms frame" if at is not rows else ""
    figure.suptitle(f"Detection as the threshold varies{frame} (x: linear below {linear:g}, "
                    f"log above)", fontsize="small")
    legend_below(figure, [plt.Line2D([], [], color=colour, marker=marker,
                                     markerfacecolor="none")
                          for _, _, colour, marker in lines],
                 [label for _, label, _, _ in lines])
    return _save(figure, out_dir, "detection_curves.png"), layout.note("detection curves")


def _suppression(rows, varied, out_dir, plt):
    power = _first(varied, POWER_COLUMNS)
    if power is None:
        return None, f"S figure skipped: the sweep does not vary the aggressor power " \
                     f"({' or '.join(POWER_COLUMNS)})"
    if "s_db" not in rows[0]:
        return None, "S figure skipped: the table has no 's_db'"
    at = [row for row in rows if _number(row["s_db"]) and _number(row[power])]
    if not at:
        return None, "S figure skipped: no point has a finite 's_db'"
    layout = _Layout(at, varied, power)
    figure, panels = layout.figure(plt, power, "S (dB)")
    lines = layout.styled()
    xs = [row[power] for row in at]
    for axes, key in panels:
        _x_axis(axes, xs, power)
        for line, label, colour, marker in lines:
            group = sorted((row for row in at if layout.panel_of(row) == key and
                            layout.line_of(row) == line), key=lambda row: row[power])
            axes.plot([row[power] for row in group], [row["s_db"] for row in group],
                      marker=marker, color=colour, markersize=5, label=label)
    legend_below(figure, [plt.Line2D([], [], color=colour, marker=marker)
                          for _, _, colour, marker in lines],
                 [label for _, label, _, _ in lines])
    return _save(figure, out_dir, "s_vs_aggressor_power.png"), layout.note("S figure")


def figures(rows, out_dir, varied):
    """Draw what ``rows`` allow into ``out_dir``; ``varied`` names the parameters the sweep
    varies. Returns ``(written, notes)``: file names, and one line per figure skipped or cut
    short."""
    if not rows:
        return [], ["figures skipped: no finished point"]
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written, notes = [], []
    for draw in (_wrong_depth, _detection_curves, _suppression):
        name, note = draw(rows, list(varied), out_dir, plt)
        if name:
            written.append(name)
        if note:
            notes.append(note)
    return written, notes
