"""Helpers the figures share (matplotlib): series styles that do not repeat, a legend below
the panels, outside the data, labelled peaks, and proportions near 0 on a log axis."""

import math

__all__ = ["MARKERS", "colours", "styles", "legend_below", "mark_peaks", "literal",
           "draw_proportion", "proportion_key"]

#: Markers of the series, in order; with the colours they tell overlapping series apart.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "h", "p", "*")


def colours(count):
    """``count`` colours, none repeated: ``tab10`` up to 10 series, ``tab20`` up to 20, else
    evenly spaced along ``turbo``."""
    from matplotlib import colormaps
    if count <= 10:
        return list(colormaps["tab10"].colors[:count])
    if count <= 20:
        return list(colormaps["tab20"].colors[:count])
    turbo = colormaps["turbo"]
    return [turbo(0.05 + 0.9 * index / (count - 1)) for index in range(count)]


def styles(count):
    """``count`` (colour, marker) pairs: distinct colours (:func:`colours`), markers in turn."""
    return [(colour, MARKERS[index % len(MARKERS)])
            for index, colour in enumerate(colours(count))]


def legend_below(figure, handles, labels, *, title=None, columns=None):
    """A legend of ``figure`` below its panels, outside every one of them; the figure must use
    the constrained layout (``plt.subplots(..., layout="constrained")``), which makes room.
    One row up to 6 entries, else 4 columns unless ``columns`` says; fewer when the legend
    would be wider than the figure, and the figure taller when it is more than half an inch
    high."""
    if not handles:
        return None
    columns = columns or (len(handles) if len(handles) <= 6 else 4)
    renderer = figure.canvas.get_renderer()
    while True:
        legend = figure.legend(handles, labels, loc="outside lower center", ncol=columns,
                               title=title, fontsize="small", title_fontsize="small",
                               frameon=False)
        box = legend.get_window_extent(renderer)
        if columns == 1 or box.width <= figure.bbox.width:
            break
        legend.remove()
        columns -= 1
    width, height = figure.get_size_inches()
    figure.set_size_inches(width, height + max(box.height / figure.dpi - 0.5, 0.0))
    return legend


def mark_peaks(axes, marks):
    """Label peaks: ``marks`` is ``[(x, y, text, colour)]`` in data coordinates. Each label
    sits above and to the right of its peak, joined to it by a thin line, and is moved up
    until it overlaps no label placed before it. Returns the annotations."""
    from matplotlib.text import Text
    renderer = axes.figure.canvas.get_renderer()
    placed, annotations = [], []
    for x, y, text, colour in sorted(marks, key=lambda mark: (mark[0], mark[1])):
        annotation = axes.annotate(
            text, (x, y), xytext=(10, 6), textcoords="offset points", fontsize="small",
            color=colour, ha="left", va="bottom",
            arrowprops={"arrowstyle": "-", "color": colour, "linewidth": 0.7, "shrinkA": 0,
                        "shrinkB": 0})
        annotation.set_in_layout(False)
        for _ in range(20):
            annotation.update_positions(renderer)
            box = Text.get_window_extent(annotation, renderer)      # the text, not the line
            if not any(box.overlaps(other) for other in placed):
                break
            annotation.xyann = (10, annotation.xyann[1] + 11)
        placed.append(box)
        annotations.append(annotation)
    return annotations


def draw_proportion(axes, x, p, low, high, *, colour, marker, floor, label=None):
    """A proportion on a log axis that cannot show 0: the estimates ``p`` above 0 as a line
    with markers, each 95 % interval ``[low, high]`` as a bar (from ``floor`` when ``low`` is
    below it, fainter where ``p`` is 0), and an open ``v`` at ``high`` where ``p`` is 0 (none
    seen: the proportion lies below it); ``label`` names the line of estimates."""
    seen = [value > 0 for value in p]
    axes.plot(x, [value if s else math.nan for value, s in zip(p, seen)], marker=marker,
              color=colour, markersize=5, label=label)
    axes.vlines(x, [max(value, floor) for value in low], high, color=colour,
                alpha=[1.0 if s else 0.5 for s in seen],
                linewidth=[1.4 if s else 0.8 for s in seen])
    zero = [(x_, h) for x_, h, s in zip(x, high, seen) if not s]
    axes.plot([point[0] for point in zero], [point[1] for point in zero], "v", color=colour,
              markerfacecolor="none", markersize=6, linestyle="none")


def proportion_key(none="none seen: 95 % upper bound"):
    """Legend handles and labels explaining :func:`draw_proportion`; ``none`` labels the
    ``v``."""
    from matplotlib.lines import Line2D
    return ([Line2D([], [], color="0.3", marker="|", linestyle="none", markersize=12),
             Line2D([], [], color="0.3", marker="v", markerfacecolor="none", linestyle="none")],
            ["95 % Wilson interval", none])


def literal(text):
    """``text`` as matplotlib draws it letter for letter: every ``$`` escaped, so that a title
    or a file name with dollars (``"cost $5 and $6"``, ``"$\\foo$"``) is never read as maths
    (nor fails to parse as maths)."""
    return str(text).replace("$", r"\$")
