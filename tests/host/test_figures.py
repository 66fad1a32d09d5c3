"""What the figures show, read back from matplotlib's objects: the sweep's (one line per compared
value in colours that do not repeat, the rest as panels, P on a log axis with its Wilson
intervals), ``fliss attack``'s, ``fliss plot``'s (victim and aggressor peaks labelled where they
are, the ``--shape`` image's rows and columns), the imager demo's and ``fliss reproduce``'s;
every legend outside the data."""

import math
import os
import sys

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_hex
from matplotlib.figure import Figure

from fliss.host.cli import main
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.host.imager.demo import compare_profiles, draw_profiles
from fliss.host.imager.report import plot_imager
from fliss.host.stream import HistogramFrame
from fliss.host.sweep.figures import MAX_PANELS, figures

sys.path.insert(0, os.path.dirname(__file__))
import imager_frames as scene                                   # noqa: E402


C = 299_792_458.0


@pytest.fixture
def drawn(monkeypatch):
    """The figures saved during a test, by file name."""
    saved = {}
    original = Figure.savefig

    def savefig(self, name, *args, **kwargs):
        saved[os.path.basename(str(name))] = self
        return original(self, name, *args, **kwargs)
    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved


def panels(figure):
    return [axes for axes in figure.axes if axes.get_visible() and axes.get_label() !=
            "<colorbar>"]


def renderer_of(figure):
    """A renderer of ``figure`` drawn again (pyplot closed it: it has lost its canvas)."""
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return canvas.get_renderer()


def outside_every_axes(figure, legend):
    renderer = renderer_of(figure)
    box = legend.get_window_extent(renderer)
    return not any(box.overlaps(axes.get_window_extent(renderer))
                   for axes in figure.axes if axes.get_visible())


def lines_by_label(axes):
    return {line.get_label(): line for line in axes.get_lines()
            if not line.get_label().startswith("_")}


# The sweep -------------------------------------------------------------------------------------

SCHEMES = ("off", "mseq", "masked")
AGGRESSORS = (1, 2, 4, 8)
POWERS = (0.5, 1.0, 2.0)


def wilson(k, n, z=1.959964):
    # Wilson score interval, written out here from its textbook form.
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return max(centre - half, 0.0), min(centre + half, 1.0)


def sweep_rows(schemes=SCHEMES, frames=50):
    """The quick example's grid: FLISS off goes wrong more often with more and stronger
    aggressors, the others never."""
    rows = []
    for scheme in schemes:
        for aggressors in AGGRESSORS:
            for power in POWERS:
                wrong = int(aggressors * power) if scheme == "off" else 0
                low, high = wilson(wrong, frames)
                rows.append({
                    "scheme": scheme, "aggressors": aggressors, "aggressor_power": power,
                    "t_int_s": 0.01, "frames": frames, "p_wrong_depth": wrong / frames,
                    "p_wrong_depth_lo": low, "p_wrong_depth_hi": high,
                    "s_db": 20.0 - aggressors * power - (5.0 if scheme == "off" else 0.0),
                    "curve_p_detect": f"[1.0, 0.9, {0.2 + 0.1 * aggressors}]",
                    "curve_false_per_frame": f"[{wrong / 10}, 0.02, 0.0]"})
    return rows


def test_p_wrong_depth_has_a_line_per_scheme_and_a_panel_per_power(tmp_path, drawn):
    rows = sweep_rows()
    written, notes = figures(rows, str(tmp_path), ["scheme", "aggressors", "aggressor_power"])
    assert "p_wrong_depth_vs_aggressors.png" in written and notes == []
    figure = drawn["p_wrong_depth_vs_aggressors.png"]
    axes = panels(figure)
    assert [a.get_title() for a in axes] == ["aggressor_power=0.5", "aggressor_power=1",
                                             "aggressor_power=2"]
    legend, = figure.legends
    assert outside_every_axes(figure, legend)
    names = [f"scheme={scheme}" for scheme in SCHEMES]
    assert [text.get_text() for text in legend.get_texts()][:3] == names
    for panel, power in zip(axes, POWERS):
        assert panel.get_yscale() == "log" and panel.get_xscale() == "log"
        lines = lines_by_label(panel)
        assert sorted(lines) == sorted(names)
        colours = {to_hex(line.get_color()) for line in lines.values()}
        assert len(colours) == 3
        for scheme in SCHEMES:
            expected = [row for row in rows if row["scheme"] == scheme and
                        row["aggressor_power"] == power]
            colour = to_hex(lines[f"scheme={scheme}"].get_color())
            estimates = lines[f"scheme={scheme}"].get_ydata()
            assert [value for value in estimates if np.isfinite(value)] == pytest.approx(
                [row["p_wrong_depth"] for row in expected if row["p_wrong_depth"] > 0])
            # a frame count of 0 is drawn as an open "v" at the Wilson upper bound
            tops = [line for line in panel.get_lines() if line.get_marker() == "v" and
                    to_hex(line.get_color()) == colour]
            zero = [row for row in expected if row["p_wrong_depth"] == 0]
            assert sorted(tops[0].get_ydata()) == pytest.approx(
                sorted(wilson(0, 50)[1] for _ in zero))
        # every point's interval is a bar: 4 aggressor counts for each of 3 schemes
        bars = [c for c in panel.collections if len(c.get_segments()) == len(AGGRESSORS)]
        assert len(bars) == 3
        low = min(panel.get_ylim())
        assert 0 < low <= min(row["p_wrong_depth_lo"] for row in rows
                              if row["p_wrong_depth_lo"] > 0)


def test_every_detection_curve_is_drawn_in_its_panel(tmp_path, drawn):
    rows = sweep_rows()
    figures(rows, str(tmp_path), ["scheme", "aggressors", "aggressor_power"])
    figure = drawn["detection_curves.png"]
    axes = panels(figure)
    assert len(axes) == len(AGGRESSORS) * len(POWERS)
    assert axes[0].get_title() == "aggressors=1, aggressor_power=0.5"
    assert axes[-1].get_title() == "aggressors=8, aggressor_power=2"
    for panel in axes:
        lines = lines_by_label(panel)
        assert sorted(lines) == sorted(f"scheme={scheme}" for scheme in SCHEMES)
        assert len({to_hex(line.get_color()) for line in lines.values()}) == 3
    assert sum(len(lines_by_label(panel)) for panel in axes) == len(rows)
    assert outside_every_axes(figure, figure.legends[0])


def test_twelve_compared_values_get_twelve_colours(tmp_path, drawn):
    schemes = [f"s{index}" for index in range(12)]
    figures(sweep_rows(schemes), str(tmp_path), ["scheme", "aggressors", "aggressor_power"])
    figure = drawn["s_vs_aggressor_power.png"]
    axes = panels(figure)
    assert [a.get_title() for a in axes] == [f"aggressors={n}" for n in AGGRESSORS]
    for panel in axes:
        lines = lines_by_label(panel)
        assert len(lines) == 12
        assert len({to_hex(line.get_color()) for line in lines.values()}) == 12
    legend, = figure.legends
    assert len({to_hex(h.get_color()) for h in legend.legend_handles}) == 12
    assert outside_every_axes(figure, legend)


def test_a_zip_partner_joins_the_line_label(tmp_path, drawn):
    rows = [dict(row, length={"mseq": 6, "masked": 4}[row["scheme"]])
            for row in sweep_rows(("mseq", "masked"))]
    figures(rows, str(tmp_path), ["scheme", "length", "aggressors", "aggressor_power"])
    axes = panels(drawn["s_vs_aggressor_power.png"])
    assert len(axes) == len(AGGRESSORS)
    assert sorted(lines_by_label(axes[0])) == ["scheme=masked, length=4",
                                               "scheme=mseq, length=6"]


@pytest.mark.filterwarnings("error")       # constrained layout found room for every panel
def test_too_many_panels_are_said(tmp_path, drawn):
    rows = [dict(row, seed_index=index) for index in range(30) for row in sweep_rows(("off",))
            if row["aggressor_power"] == 1.0]
    _, notes = figures(rows, str(tmp_path), ["aggressors", "seed_index"])
    # P(wrong depth): a line per seed_index (30 colours); detection curves: a panel per one
    assert notes[0] == f"detection curves: the first {MAX_PANELS} of 30 panels drawn (one " \
                       f"per seed_index)"
    lines = lines_by_label(panels(drawn["p_wrong_depth_vs_aggressors.png"])[0])
    assert len({to_hex(line.get_color()) for line in lines.values()}) == 30
    assert len(panels(drawn["detection_curves.png"])) == MAX_PANELS


# fliss attack ----------------------------------------------------------------------------------

def test_attack_figure_gives_every_source_its_colour_and_keeps_legends_off_the_data(
        tmp_path, drawn, capsys):
    assert main(["attack", "--pulses", "3000", "--scene-pulses", "3000", "--acquisition-pulses",
                 "1000", "--no-unknown-taps", "--table", "-",
                 "--figure", str(tmp_path / "attack.png")]) == 0
    capsys.readouterr()
    figure = drawn["attack.png"]
    bars, *families = figure.axes
    labels = [label.get_text() for label in bars.get_yticklabels()]
    assert len(labels) == 11 and labels[0] == "off" and labels[-1] == "random Wm=6"
    assert [axes.get_title(loc="left") for axes in families] == ["off", "mseq", "masked",
                                                                 "keyed, random"]
    lines = {label: line for axes in families for label, line in lines_by_label(axes).items()}
    assert sorted(lines) == sorted(labels)
    assert len({to_hex(line.get_color()) for line in lines.values()}) == 11
    for axes in families:
        assert outside_every_axes(figure, axes.get_legend())
    assert outside_every_axes(figure, figure.legends[0])


def test_attack_figure_draws_a_few_sources_in_one_panel(tmp_path, drawn, capsys):
    assert main(["attack", "--sources", "off,mseq,keyed", "--lengths", "8", "--pulses", "3000",
                 "--scene-pulses", "3000", "--acquisition-pulses", "1000", "--no-unknown-taps",
                 "--table", "-", "--figure", str(tmp_path / "attack.png")]) == 0
    capsys.readouterr()
    bars, s_panel = drawn["attack.png"].axes
    assert sorted(lines_by_label(s_panel)) == ["keyed Wm=6", "mseq L=8", "off"]


# fliss plot of histograms ----------------------------------------------------------------------

SHIFT = 3
BIN_S = 50e-12 * (1 << SHIFT)
VICTIM_S = 2 * 4.0 / C                  # a target at 4 m
AGGRESSOR_S = VICTIM_S + 75e-9          # the aggressor 75 ns after the victim


def histogram_capture(path, victim=400.0, aggressor=500.0, seed=1):
    """A histogram capture with the victim's echo and a taller aggressor peak (2.1 ns FWHM
    Gaussians over a flat background), Poisson counts."""
    edges = np.arange((8192 >> SHIFT) + 1) * BIN_S
    sigma = 2.1e-9 / 2.3548

    def gaussian(centre, photons):
        cdf = np.array([0.5 * (1 + math.erf((edge - centre) / (sigma * math.sqrt(2))))
                        for edge in edges])
        return photons * np.diff(cdf)
    means = 0.3 + gaussian(VICTIM_S, victim) + gaussian(AGGRESSOR_S, aggressor)
    counts = np.random.default_rng(seed).poisson(means).astype(np.uint32)
    with CaptureWriter(str(path), mode="histogram", identity=scene.identity(),
                       configuration=scene.configuration(pixel_bits=0, bin_shift=SHIFT,
                                                         delay_mode=0, aggressor=1)) as writer:
        writer.add_histogram(HistogramFrame(0, SHIFT, counts, True, 0, 1.0))


def labels_of(axes):
    return {text.get_text().split(" ")[0]: text for text in axes.texts}


def test_plot_labels_the_victim_and_the_aggressor_where_they_are(tmp_path, drawn, capsys):
    histogram_capture(tmp_path / "a.h5")
    assert main(["plot", str(tmp_path / "a.h5"), "-o", str(tmp_path / "a.png"),
                 "--victim-tof", f"{VICTIM_S * 1e9:.3f}ns"]) == 0
    capsys.readouterr()
    figure = drawn["a.png"]
    axes, = figure.axes
    texts = labels_of(axes)
    assert sorted(texts) == ["aggressor", "victim"]
    for name, truth in (("victim", VICTIM_S), ("aggressor", AGGRESSOR_S)):
        assert texts[name].xy[0] == pytest.approx(truth * 1e9, abs=BIN_S * 1e9)
        assert texts[name].get_text() == f"{name} {texts[name].xy[0]:.1f} ns"
    legend, = figure.legends
    assert outside_every_axes(figure, legend)
    label = legend.get_texts()[0].get_text()
    assert label.startswith("a.h5 (FLISS off, aggressor on): S = -")   # the aggressor is taller


def test_plot_without_the_victims_tof_names_no_victim_with_fliss_off(tmp_path, drawn, capsys):
    # FLISS off: the aggressor's peak is as sharp as the victim's echo (and here taller); one
    # histogram cannot tell them apart, so neither is called the victim and there is no S.
    histogram_capture(tmp_path / "a.h5")
    assert main(["plot", str(tmp_path / "a.h5"), "-o", str(tmp_path / "a.png")]) == 0
    capsys.readouterr()
    figure = drawn["a.png"]
    texts = [text.get_text() for text in figure.axes[0].texts]
    assert len(texts) == 2 and all(text.endswith(" ns (role unknown)") for text in texts)
    assert sorted(text.xy[0] for text in figure.axes[0].texts) == [
        pytest.approx(VICTIM_S * 1e9, abs=BIN_S * 1e9),
        pytest.approx(AGGRESSOR_S * 1e9, abs=BIN_S * 1e9)]
    label = figure.legends[0].get_texts()[0].get_text()
    assert label == "a.h5 (FLISS off, aggressor on): roles unknown, S unknown"


def test_labels_of_two_captures_do_not_overlap(tmp_path, drawn, capsys):
    histogram_capture(tmp_path / "a.h5")
    histogram_capture(tmp_path / "b.h5", victim=380.0, seed=2)
    assert main(["plot", str(tmp_path / "a.h5"), str(tmp_path / "b.h5"), "-o",
                 str(tmp_path / "ab.png"), "--victim-tof", f"{VICTIM_S * 1e9:.3f}ns"]) == 0
    capsys.readouterr()
    figure = drawn["ab.png"]
    renderer = renderer_of(figure)
    from matplotlib.text import Text
    boxes = [Text.get_window_extent(text, renderer) for text in figure.axes[0].texts]
    assert len(boxes) == 4
    assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


# The imager ------------------------------------------------------------------------------------

def depth_capture(path, frames=3):
    truth = np.full((8, 8), 4.0)
    truth[2:5, 3:7] = 2.5
    depths = np.tile(truth.ravel(), (frames, 1)) + 0.3 * np.arange(frames)[:, None]
    depths[1, 10] = np.nan
    with CaptureWriter(str(path), mode="depth", identity=scene.identity(),
                       configuration=scene.configuration(pixel_bits=6, first_pixel=0)) as writer:
        for frame in scene.depth_frames(depths, first=0):
            writer.add_frame(frame)
    return read_capture(str(path))


def test_the_8x8_depth_image_names_its_rows_and_columns(tmp_path, drawn):
    capture = depth_capture(tmp_path / "d.h5")
    plot_imager(capture, str(tmp_path / "d.png"), shape="8x8", quiet=True)
    image = drawn["d.png"].axes[0]
    assert [t.get_text() for t in image.get_xticklabels()] == [str(i) for i in range(8)]
    assert [t.get_text() for t in image.get_yticklabels()] == [str(i) for i in range(8)]
    assert (image.get_xlabel(), image.get_ylabel()) == ("column", "row")
    assert image.get_title() == "d.h5: depth (pixel 0 + 8 × row + column)"
    picture, = image.get_images()
    # row 2, column 3: the object, 2.5 m plus 0.3 m a frame, median over the 3 frames
    assert picture.get_array()[2, 3] == pytest.approx(2.8, abs=0.02)


def test_the_grid_of_depth_images_shares_one_colour_scale(tmp_path, drawn):
    capture = depth_capture(tmp_path / "d.h5")
    plot_imager(capture, str(tmp_path / "g.png"), shape="8x8", frames="grid", quiet=True)
    limits = {axes.get_images()[0].get_clim() for axes in drawn["g.png"].axes
              if axes.get_images()}
    assert len(limits) == 1


def test_the_imager_demo_figure_explains_every_mark_outside_the_data(tmp_path, drawn):
    truth = np.array([4.0, 4.0, 2.5, 2.5, 4.0, 4.0])
    off = np.tile(truth, (3, 1))
    off[:, 1] = 15.0                                    # a ghost depth at pixel 1
    draw_profiles(compare_profiles(off, np.tile(truth, (3, 1)), truth), str(tmp_path / "i.png"))
    figure = drawn["i.png"]
    legend, = figure.legends
    labels = [text.get_text() for text in legend.get_texts()]
    assert labels == ["single frames (3)", "scene", "measured (median over the frames)",
                      "wrong depth (more than 0.15 m from the scene)"]
    grey = lines_by_label(figure.axes[0])["single frames (3)"]
    assert to_hex(legend.legend_handles[0].get_color()) == to_hex(grey.get_color())
    assert outside_every_axes(figure, legend)


# fliss reproduce -------------------------------------------------------------------------------

def test_reproduce_figures_label_the_peaks_and_keep_legends_off_the_data(tmp_path, drawn,
                                                                          capsys):
    assert main(["-q", "reproduce", "--acquisitions", "3", "--t-int", "10ms", "20ms",
                 "--lengths", "3", "6", "--mask-widths", "6", "--jobs", "1",
                 "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    texts = labels_of(drawn["fig08_aggressor.png"].axes[0])
    assert texts["victim"].xy[0] == pytest.approx(VICTIM_S * 1e9, abs=0.1)
    assert texts["aggressor"].xy[0] == pytest.approx(AGGRESSOR_S * 1e9, abs=0.1)
    for name in ("fig09_suppression_L.png", "fig10_histograms.png", "fig11_deviations.png",
                 "fig12_suppression_Wm.png"):
        figure = drawn[name]
        assert all(axes.get_legend() is None for axes in figure.axes), name
        assert outside_every_axes(figure, figure.legends[0]), name
    legend = drawn["fig11_deviations.png"].legends[0]
    assert [t.get_text() for t in legend.get_texts()] == ["T_int = 10 ms", "T_int = 20 ms"]
    assert len({to_hex(h.get_color()) for h in legend.legend_handles}) == 2
