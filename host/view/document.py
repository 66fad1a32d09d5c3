"""The page of the live view: a Bokeh document per browser session, redrawn from the
:class:`~fliss.host.view.feed.Feed` by a periodic callback on the server.

Every number and plot is a Bokeh model updated from Python; the browser runs BokehJS only. What
the page shows depends on the readout: histograms (linear and log) and the peak table for
histogram, image and raw readouts; the depth profile (an image with a shape) and the intensity
of each pixel for image and depth readouts.
"""

import html
import math

import numpy as np
from bokeh.layouts import row
from bokeh.models import (Button, ColorBar, ColumnDataSource, CustomJS, Div,
                          LinearColorMapper, RadioButtonGroup, Range1d)
from bokeh.palettes import Magma256, Viridis256
from bokeh.plotting import figure

from ..units import format_time
from .feed import Feed, Picture, Status


__all__ = ["WINDOW", "build_document", "PageFlow", "status_html", "peaks_html"]

#: Points at most in a drawn histogram: a browser redraws 1024 many times a second, and 8192
#: several times slower. Finer histograms are drawn in wider bins (sums of neighbours).
MAX_POINTS = 1024

#: Updates a page may have on the way (sent, not taken yet): two, so that the time an update
#: takes to reach the page and its answer to come back (the GIL of a busy capture on one side,
#: a page still painting the last update on the other) does not hold a page to half the rate.
WINDOW = 2

#: Rows of the peak table (the tallest peaks).
MAX_PEAKS = 6

#: Colours of the peak markers by role.
_ROLE_COLOURS = {"victim": "#1b9e77", "aggressor": "#d95f02", "unknown": "#7570b3", "": "#7570b3"}

_STYLE = {"font-size": "14px", "font-family": "sans-serif"}


def build_document(doc, feed: Feed, period_s: float, notify=None) -> "PageFlow":
    """Fill ``doc`` (a new session's document) with the view of ``feed``, redrawn every
    ``period_s`` seconds.

    Flow control: an update goes to the page only while the page has fewer than
    :data:`WINDOW` updates on the way (the page's glue hands the number of each update it has
    taken back, :class:`PageFlow`); otherwise the server sends nothing, and the page gets the
    latest frame when it is ready again. A page that cannot keep up (slow, stalled, a tab the
    browser keeps waiting) thus costs the server at most :data:`WINDOW` updates, and no
    acquisition ever waits for a page. The updates a page missed so are counted, shown on its
    status line and, if ``notify`` is given, said in one line when the page goes. Returns the
    page's :class:`PageFlow`."""
    setup = feed.setup
    doc.title = f"FLISS view: {setup.source}"
    # (seq: of the picture drawn; checked: the feed's at the last tick)
    state = {"summed": False, "seq": None, "drawn_summed": None, "bins": None, "checked": None}
    flow = PageFlow(doc)

    title = Div(text=_title_html(feed), styles=dict(_STYLE, **{"font-size": "16px"}))
    # Each part is a root of its own, and the texts are of fixed height: a text that changes
    # lays out only itself. Laying out the whole page, plots and all, at each update would
    # take most of the browser's time.
    status = Div(text="", css_classes=["fliss-status"], styles=_STYLE,
                 sizing_mode="stretch_width", height=66)
    parts = [title, status, flow.sent, flow.taken]

    # Data that count photons are drawn as a histogram; data of pixels as a profile or image.
    kind = setup.kind
    histogram, imager = kind.counted, kind.imager
    show = RadioButtonGroup(labels=["latest frame", "sum of frames"], active=0, width=260)
    clear = Button(label="clear the sum", width=120)
    if not kind.framed:
        show.labels, show.disabled = ["sum of events"], True
    elif not kind.counted:
        show.labels, show.disabled, clear.visible = ["latest frame"], True, False

    def choose(attr, old, new):
        state["summed"] = bool(new)
    show.on_change("active", choose)
    clear.on_click(feed.clear_sum)
    if histogram:
        parts.append(row(show, clear))

    curve = ColumnDataSource(data=dict(t=[], counts=[], positive=[]))
    marks = ColumnDataSource(data=dict(t=[], y=[], colour=[]))
    table = Div(text="", css_classes=["fliss-peaks"], styles=_STYLE,
                sizing_mode="stretch_width", height=40 + 22 * (MAX_PEAKS + 1))
    linear = log = None
    if histogram:
        linear = _histogram_figure("histogram", "linear")
        linear.step("t", "counts", source=curve, mode="center", line_width=1.2)
        linear.scatter("t", "y", source=marks, marker="inverted_triangle", size=11,
                       color="colour")
        log = _histogram_figure("histogram, log scale", "log")
        log.x_range = linear.x_range
        log.step("t", "positive", source=curve, mode="center", line_width=1.2)
        parts += [row(linear, log, sizing_mode="stretch_width"), table]

    profile = ColumnDataSource(data=dict(pixel=[], depth=[], intensity=[]))
    depth_image = ColumnDataSource(data=dict(image=[]))
    intensity_image = ColumnDataSource(data=dict(image=[], x=[], dw=[], y=[], dh=[]))
    if imager:
        parts.append(row(*_imager_figures(setup, profile, depth_image, intensity_image),
                         sizing_mode="stretch_width"))

    def update(first=False):
        if flow.behind:
            # The page has yet to take the updates on the way: it gets the latest state later.
            if flow.loaded and feed.seq != state["checked"]:
                flow.missed += 1
                flow.held = True
            state["checked"] = feed.seq
            return
        state["checked"] = feed.seq
        # (the changes of an update go to the browser as one message, its number last)
        doc.hold("combine")
        try:
            picture = feed.picture(state["summed"])
            status.text = status_html(feed, feed.status(), picture, flow.missed)
            if picture.seq != state["seq"] or picture.summed != state["drawn_summed"]:
                state["seq"], state["drawn_summed"] = picture.seq, picture.summed
                if histogram:
                    _draw_histogram(picture, curve, marks, table, state, (linear, log))
                if imager:
                    _draw_imager(picture, setup, profile, depth_image, intensity_image)
            if not first:
                flow.send()
        finally:
            doc.unhold()

    def gone(context):
        if notify is not None and flow.missed:
            notify(f"a page that left had missed {flow.missed} of {flow.updates + flow.missed} "
                   f"updates, drawing more slowly than they came (it was shown the latest "
                   f"frame each time)")

    update(first=True)
    flow.catch_up = update
    for part in parts:
        doc.add_root(part)
    doc.add_periodic_callback(update, max(1, round(period_s * 1000)))
    doc.on_session_destroyed(gone)
    return flow


class PageFlow:
    """The flow control of a page: two hidden models and counts.

    The server numbers each update (:meth:`send`) in ``sent.tags``; the page, once it has
    applied the update (and once it has loaded: a session's first updates may come before),
    copies the number into ``taken.tags``, which comes back to the server. ``missed`` counts
    the updates held back, each at a new frame, while the page had :data:`WINDOW` updates on
    the way.
    """

    def __init__(self, doc):
        self.sent = Div(visible=False, tags=[0], name="fliss-sent")
        self.taken = Div(visible=False, tags=[0], name="fliss-taken")
        take = CustomJS(args=dict(sent=self.sent, taken=self.taken),
                        code="taken.tags = sent.tags.slice()")
        self.sent.js_on_change("tags", take)
        doc.js_on_event("document_ready", take)
        #: Updates sent to the page, the last the page took, updates it missed.
        self.updates = self.took = self.missed = 0
        #: Whether an update was held back since the last one sent; then ``catch_up`` (the
        #: document's update) is called as soon as the page takes that one, rather than at
        #: the next period: a page a little slower than the period is not held to half of it.
        self.held = False
        self.catch_up = None
        self.taken.on_change("tags", self._took)

    def _took(self, attr, old, new):
        self.took = int(new[0]) if new else self.took
        if self.held and not self.behind and self.catch_up is not None:
            self.catch_up()

    def send(self) -> None:
        """Number the update being made (call it last, in the update's hold)."""
        self.updates += 1
        self.held = False
        self.sent.tags = [self.updates]

    @property
    def behind(self) -> bool:
        """Whether the page has :data:`WINDOW` updates it has not taken yet."""
        return self.updates - self.took >= WINDOW

    @property
    def loaded(self) -> bool:
        """Whether the page has taken an update (it has loaded)."""
        return self.took > 0


def _title_html(feed):
    setup = feed.setup
    what = setup.kind.what
    source = "board on" if setup.live else "replay of"
    integration = format_time(setup.integration_s) if setup.integration_s else "?"
    return (f"<b>FLISS live view</b> &mdash; {source} {html.escape(setup.source)}: {what}, "
            f"{integration} integration")


def _histogram_figure(title, scale):
    plot = figure(title=title, height=300, sizing_mode="stretch_width", y_axis_type=scale,
                  x_axis_label="time of flight (ns)", y_axis_label="counts per bin",
                  tools="pan,xwheel_zoom,box_zoom,reset,save", output_backend="canvas")
    plot.title.text_font_size = "14px"
    plot.toolbar.logo = None
    return plot


def _imager_figures(setup, profile, depth_image, intensity_image):
    figures = []
    if setup.shape is None:
        depth = figure(title="depth profile", height=300, sizing_mode="stretch_width",
                       x_axis_label="pixel address", y_axis_label="depth (m)",
                       tools="pan,box_zoom,reset,save")
        depth.line("pixel", "depth", source=profile, line_width=1.5)
        depth.scatter("pixel", "depth", source=profile, size=5)
    else:
        rows, columns = setup.shape
        depth = figure(title="depth (m)", height=300, sizing_mode="stretch_width",
                       x_range=Range1d(0, columns), y_range=Range1d(rows, 0),
                       x_axis_label="column", y_axis_label="row",
                       tools="pan,box_zoom,reset,save", match_aspect=True)
        # (row r of the image spans y = r to r + 1; the y axis runs down, row 0 on top)
        mapper = LinearColorMapper(palette=Viridis256, nan_color="#dddddd")
        depth.image("image", x=0, y=0, dw=columns, dh=rows, source=depth_image,
                    color_mapper=mapper)
        depth.add_layout(ColorBar(color_mapper=mapper, title="m", width=12), "right")
    figures.append(depth)
    if setup.kind.counted:       # (per-pixel histograms)
        intensity = figure(title="intensity: counts per bin and pixel", height=300,
                           sizing_mode="stretch_width", x_axis_label="time of flight (ns)",
                           y_axis_label="pixel address", tools="pan,box_zoom,reset,save")
        mapper = LinearColorMapper(palette=Magma256)
        intensity.image("image", x="x", y="y", dw="dw", dh="dh", source=intensity_image,
                        color_mapper=mapper)
        intensity.add_layout(ColorBar(color_mapper=mapper, width=12), "right")
    else:
        intensity = figure(title="peak height (counts)", height=300,
                           sizing_mode="stretch_width", x_axis_label="pixel address",
                           y_axis_label="counts", tools="pan,box_zoom,reset,save")
        intensity.vbar("pixel", top="intensity", width=0.8, source=profile)
    for plot in (depth, intensity):
        plot.title.text_font_size = "14px"
        plot.toolbar.logo = None
    figures.append(intensity)
    return figures


def _draw_histogram(picture: Picture, curve, marks, table, state, plots):
    table.text = peaks_html(picture)
    if picture.counts is None:
        curve.data = dict(t=[], counts=[], positive=[])
        marks.data = dict(t=[], y=[], colour=[])
        return
    bins = len(picture.counts)
    group = max(1, bins // MAX_POINTS)
    counts = picture.counts.reshape(-1, group).sum(axis=1).astype(np.float32)
    # (a log axis has no 0: empty bins are drawn at the bottom, at half a count)
    positive = np.maximum(counts, np.float32(0.5))
    if state["bins"] != bins:
        state["bins"] = bins
        time_ns = picture.time_ns.reshape(-1, group).mean(axis=1).astype(np.float32)
        curve.data = dict(t=time_ns, counts=counts, positive=positive)
        width_ps = (picture.time_ns[1] - picture.time_ns[0]) * group * 1e3 if bins > 1 else 0
        drawn = f"{bins} bins" if group == 1 else \
            f"{bins} bins drawn as {bins // group} of {width_ps:.4g} ps"
        for plot, text in zip(plots, ("histogram", "histogram, log scale")):
            plot.title.text = f"{text} ({drawn})"
            plot.yaxis.axis_label = "counts per bin" if group == 1 else \
                f"counts per {width_ps:.4g} ps"
    else:
        curve.data.update(counts=counts, positive=positive)
    level = picture.background if math.isfinite(picture.background) else 0.0
    marks.data = dict(t=[peak.tof_ns for peak in picture.peaks],
                      y=[(peak.height + level) * group for peak in picture.peaks],
                      colour=[_ROLE_COLOURS[peak.role] for peak in picture.peaks])


def _draw_imager(picture: Picture, setup, profile, depth_image, intensity_image):
    if picture.pixels is None:
        return
    depth = np.asarray(picture.depth_m, dtype=float)
    profile.data = dict(pixel=picture.pixels, depth=depth,
                        intensity=np.asarray(picture.intensity, dtype=float))
    if setup.shape is not None and len(depth) == setup.shape[0] * setup.shape[1]:
        depth_image.data = dict(image=[depth.reshape(setup.shape)])
    if picture.image is not None and picture.time_ns is not None:
        step = picture.time_ns[1] - picture.time_ns[0] if len(picture.time_ns) > 1 else 1.0
        intensity_image.data = dict(
            image=[np.asarray(picture.image, dtype=np.float32)], x=[0.0],
            dw=[len(picture.time_ns) * step], y=[picture.pixels[0] - 0.5],
            dh=[len(picture.pixels)])


def status_html(feed: Feed, status: Status, picture: Picture, skipped: int = 0) -> str:
    """The status lines: what is shown, frames and rates, and the updates this page missed
    (``skipped``: it had not taken the one before)."""
    setup = feed.setup
    if not picture.frames:
        shown = "nothing yet"
    elif picture.summed or not setup.kind.framed:
        shown = f"sum of <span class='n-summed'>{picture.frames}</span> " + \
            ("frames" if setup.kind.framed else "event batches") + \
            f", <span class='n-total'>{picture.total}</span> counts"
    else:
        shown = f"frame <span class='n-frame'>{picture.frame}</span>" + \
            ("" if picture.complete else " (incomplete)") + \
            (f", <span class='n-total'>{picture.total}</span> counts" if setup.kind.counted
             else "")
    if picture.pixels is not None:
        detected = int(np.isfinite(picture.depth_m).sum())
        shown += (f" &middot; <span class='n-detected'>{detected}</span> of "
                  f"{len(picture.pixels)} pixels detect a target")
    rate_unit = "counts/s of integration" if setup.kind.framed else "events/s"
    drops = "&ndash; " if status.drop_rate_hz is None else _si(status.drop_rate_hz)
    counted = f"count rate {_si(status.count_rate_hz)}{rate_unit} &middot; " \
        if setup.kind.counted else ""
    received = "frames" if setup.kind.framed else "event batches"
    lines = [
        f"<b class='n-state'>{html.escape(status.state)}</b> &middot; showing {shown}",
        f"{received} received <span class='n-frames'>{status.frames}</span>, "
        f"lost <span class='n-lost'>{status.lost}</span>, "
        f"incomplete {status.incomplete} &middot; "
        f"<span class='n-rate'>{status.frame_rate_hz:.1f}</span> {received}/s",
        f"{counted}dropped on the board {drops}events/s &middot; "
        f"link: {status.corrupt} corrupt frames, {status.missing} missing packets"
        + (f" &middot; this page missed <span class='n-skipped'>{skipped}</span> updates "
           f"(too slow to draw them)" if skipped else ""),
    ]
    return "<br>".join(lines)


def peaks_html(picture: Picture) -> str:
    """The suppression and the table of the tallest peaks, as HTML."""
    if picture.counts is None:
        return ""
    if not picture.peaks:
        return "<i>no peak above the detection threshold</i>"
    if picture.suppression_db is not None:
        relation = "&ge;" if picture.suppression_limited else "="
        suppression = (f"S {relation} <span class='n-s'>{picture.suppression_db:.2f}</span> dB"
                       + (f" [{html.escape(picture.note)}]" if picture.note else ""))
    elif picture.note:
        suppression = f"S unknown [{html.escape(picture.note)}]"
    elif len(picture.peaks) == 1:
        suppression = "S: one peak, no aggressor to compare it with"
    else:
        suppression = "S: which peak is the victim's? (--victim-tof)"
    head = ("<tr><th>peak</th><th>role</th><th>ToF (ns)</th><th>distance (m)</th>"
            "<th>FWHM (ns)</th><th>height (counts/bin)</th></tr>")
    body = "".join(
        f"<tr><td>{index + 1}</td><td>{peak.role}</td><td class='tof'>{peak.tof_ns:.3f}</td>"
        f"<td>{peak.distance_m:.3f}</td><td class='fwhm'>{peak.fwhm_ns:.3f}</td>"
        f"<td class='height'>{peak.height:.4g}</td></tr>"
        for index, peak in enumerate(picture.peaks[:MAX_PEAKS]))
    more = len(picture.peaks) - MAX_PEAKS
    cell = "style='padding: 1px 14px; text-align: right'"
    table = (f"<table style='border-collapse: collapse'>{head}{body}</table>"
             .replace("<td>", f"<td {cell}>").replace("<td class", f"<td {cell} class")
             .replace("<th>", f"<th {cell}>"))
    return (f"<div style='margin-bottom: 4px'><b>{suppression}</b> &middot; background "
            f"{picture.background:.4g} counts per bin"
            + (f" &middot; the {MAX_PEAKS} tallest of {len(picture.peaks)} peaks"
               if more > 0 else "") + f"</div>{table}")


def _si(value):
    # "1.23 k", "5 ": a number and its prefix, before a unit
    if not math.isfinite(value):
        return "&ndash; "
    for factor, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if abs(value) >= factor * 0.9995:       # (999.9 k is 1 M at 3 digits)
            return f"{value / factor:.3g} {prefix}"
    return f"{value:.3g} "
