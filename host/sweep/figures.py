"""Figures of ``fliss sweep``, drawn from the table's rows (PNG, matplotlib).

Each figure needs some columns and a parameter that varies; when the sweep lacks them the figure
is skipped and :func:`figures` says why. One line is drawn per combination of the other varied
parameters, labelled with them.
"""

import json
import math
import os


__all__ = ["figures", "POWER_COLUMNS", "CURVE_COLUMNS", "FRAME_T_INT_S"]


#: Parameter giving the aggressors' power, first found wins.
POWER_COLUMNS = ("aggressor_power_db", "aggressor_power", "power_db", "power")
#: The frame length of the P(wrong depth) figure: 10 ms.
FRAME_T_INT_S = 10e-3

#: Detection curve of a point: JSON lists of equal length, P(detect) and false targets per frame.
CURVE_COLUMNS = ("curve_p_detect", "curve_false_per_frame")


def _first(columns, names):
    return next((name for name in names if name in columns), None)


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) and \
        value is not None and math.isfinite(value)


def _groups(rows, varied, exclude):
    """Rows grouped by the varied parameters not in ``exclude``: ``{label: rows}``."""
    names = [name for name in varied if name not in exclude]
    groups = {}
    for row in rows:
        label = ", ".join(f"{name}={row.get(name)}" for name in names) or "all points"
        groups.setdefault(label, []).append(row)
    return groups


def _save(figure, out_dir, name):
    figure.tight_layout()
    figure.savefig(os.path.join(out_dir, name), dpi=120)
    import matplotlib.pyplot as plt
    plt.close(figure)
    return name


def _wrong_depth(rows, varied, out_dir, plt):
    if "aggressors" not in varied:
        return None, "P(wrong depth) figure skipped: the sweep does not vary 'aggressors'"
    if "p_wrong_depth" not in rows[0]:
        return None, "P(wrong depth) figure skipped: the table has no 'p_wrong_depth'"
    at = rows
    if "t_int_s" in rows[0]:
        at = [row for row in rows if _number(row["t_int_s"]) and
              math.isclose(row["t_int_s"], FRAME_T_INT_S, rel_tol=1e-6)]
        if not at:
            return None, "P(wrong depth) figure skipped: no point has t_int_s = 0.01 (10 ms)"
    figure, axes = plt.subplots(figsize=(7, 4.5))
    for label, group in _groups(at, varied, {"aggressors", "t_int_s"}).items():
        group = sorted((row for row in group if _number(row["p_wrong_depth"])),
                       key=lambda row: row["aggressors"])
        if not group:
            continue
        x = [row["aggressors"] for row in group]
        y = [row["p_wrong_depth"] for row in group]
        error = None
        if "p_wrong_depth_lo" in group[0] and "p_wrong_depth_hi" in group[0]:
            error = [[max(v - (row["p_wrong_depth_lo"] or v), 0.0) for v, row in zip(y, group)],
                     [max((row["p_wrong_depth_hi"] or v) - v, 0.0) for v, row in zip(y, group)]]
        axes.errorbar(x, y, yerr=error, marker="o", capsize=3, label=label)
    axes.set_xlabel("aggressors")
    axes.set_ylabel("P(wrong depth) per 10 ms frame")
    axes.set_yscale("symlog", linthresh=1e-4)
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize="small")
    return _save(figure, out_dir, "p_wrong_depth_vs_aggressors.png"), None


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
    at = [row for row in rows if "t_int_s" not in row or
          (_number(row["t_int_s"]) and math.isclose(row["t_int_s"], FRAME_T_INT_S, rel_tol=1e-6))]
    at = at or rows
    shown = at[:12]
    figure, axes = plt.subplots(figsize=(7, 4.5))
    for row in shown:
        pairs = _curve(row)
        if pairs:
            label = ", ".join(f"{name}={row.get(name)}" for name in varied) or "all points"
            axes.plot([p[0] for p in pairs], [p[1] for p in pairs], marker=".", label=label)
    axes.set_xlabel("false targets per frame")
    axes.set_ylabel("P(detect)")
    axes.set_xscale("symlog", linthresh=1e-3)
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize="x-small")
    if len(at) > len(shown):
        axes.set_title(f"first {len(shown)} of {len(at)} points", fontsize="small")
    return _save(figure, out_dir, "detection_curves.png"), None


def _suppression(rows, varied, out_dir, plt):
    power = _first(varied, POWER_COLUMNS)
    if power is None:
        return None, f"S figure skipped: the sweep does not vary the aggressor power " \
                     f"({' or '.join(POWER_COLUMNS)})"
    if "s_db" not in rows[0]:
        return None, "S figure skipped: the table has no 's_db'"
    figure, axes = plt.subplots(figsize=(7, 4.5))
    for label, group in _groups(rows, varied, {power}).items():
        group = sorted((row for row in group if _number(row["s_db"]) and _number(row[power])),
                       key=lambda row: row[power])
        if group:
            axes.plot([row[power] for row in group], [row["s_db"] for row in group],
                      marker="o", label=label)
    axes.set_xlabel(power)
    axes.set_ylabel("S (dB)")
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize="small")
    return _save(figure, out_dir, "s_vs_aggressor_power.png"), None


def figures(rows, out_dir, varied):
    """Draw what ``rows`` allow into ``out_dir``; ``varied`` names the parameters the sweep
    varies. Returns ``(written, notes)``: file names, and one line per figure skipped."""
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
