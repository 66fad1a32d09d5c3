"""Whose is each peak (`fliss analyze`, `fliss plot`): told by the user, by the settings a capture
records, or unknown, and no suppression worked out from a guess; the JSON's suppression says
whether it is a value or a lower bound; the plots draw titles and file names letter for letter.

The histograms are built here: Gaussian echoes of the paper's 2.1 ns FWHM at known times over a
flat background, Poisson counts."""

import json
import math
import os
import sys

import numpy as np
import pytest
from matplotlib.figure import Figure

from fliss.hdl.delay.modes import DelayMode
from fliss.host.analysis import analyze
from fliss.host.cli import main
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.host.roles import assign, relation
from fliss.analysis.peaks import Peak
from fliss.host.stream import HistogramFrame

sys.path.insert(0, os.path.dirname(__file__))
import imager_frames as scene                                   # noqa: E402


C = 299_792_458.0
SHIFT = 3
BIN_S = 50e-12 * (1 << SHIFT)
VICTIM_S = 2 * 4.0 / C                  # a target at 4 m: 26.69 ns
AGGRESSOR_S = VICTIM_S + 75e-9          # the aggressor 75 ns after the victim

OFF = dict(delay_mode=DelayMode.OFF.value, aggressor=1)
ON = dict(delay_mode=DelayMode.MASKED.value, mask_width=6, aggressor=1)
ALONE = dict(delay_mode=DelayMode.OFF.value, aggressor=0)


def counts(echoes, background=0.3, seed=1):
    """Poisson counts of bins of BIN_S: ``echoes`` as (time, photons)."""
    edges = np.arange((8192 >> SHIFT) + 1) * BIN_S
    sigma = 2.1e-9 / (2 * math.sqrt(2 * math.log(2)))
    means = np.full(len(edges) - 1, background)
    for centre, photons in echoes:
        cdf = np.array([0.5 * (1 + math.erf((edge - centre) / (sigma * math.sqrt(2))))
                        for edge in edges])
        means += photons * np.diff(cdf)
    return np.random.default_rng(seed).poisson(means).astype(np.uint32)


def write(path, echoes, settings, seed=1):
    with CaptureWriter(str(path), mode="histogram", identity=scene.identity(),
                       configuration=scene.configuration(pixel_bits=0, bin_shift=SHIFT,
                                                         **settings)) as writer:
        writer.add_histogram(HistogramFrame(0, SHIFT, counts(echoes, seed=seed), True, 0, 1.0))
    return str(path)


def fliss(capsys, *argv):
    status = main([str(part) for part in argv])
    return (status, *capsys.readouterr())


def peak_rows(out):
    """(ToF ns, role) of the rows of the peak table."""
    return [(float(line.split()[1]), line.split()[-1]) for line in out.splitlines()
            if line.strip()[:1].isdigit()]


# The roles from the settings ------------------------------------------------------------------

def test_the_relation_of_the_aggressor_from_the_registers():
    registers = scene.configuration(pixel_bits=0)
    assert relation({**registers, **ALONE})[0] == "off"
    assert relation({**registers, **OFF})[0] == "coherent"
    assert relation({**registers, **ON})[0] == "spread"
    # FLISS off but the aggressor with delays of its own: spread too
    assert relation({**registers, **OFF, "aggressor_delay_mode": 1})[0] == "spread"
    # The aggressor repeating the victim's very delays (an attacker's copy): coherent
    same = {**registers, **ON, "aggressor_delay_mode": DelayMode.MASKED.value,
            "aggressor_mask_width": 6, "aggressor_seed": registers["seed"],
            "aggressor_period": registers["period"]}
    assert relation(same)[0] == "coherent"
    assert relation({**registers, **OFF, "aggressor_period": registers["period"] + 1})[0] == \
        "unknown"
    assert relation({})[0] == "unknown"


def test_with_fliss_off_two_peaks_have_unknown_roles_and_no_s(tmp_path, capsys):
    # The aggressor's peak (101.7 ns) taller than the victim's echo (26.7 ns): the old analysis
    # called it the victim and gave S the wrong sign.
    path = write(tmp_path / "off.h5", [(VICTIM_S, 300), (AGGRESSOR_S, 500)], OFF)
    status, out, err = fliss(capsys, "analyze", path)
    assert (status, err) == (0, "")
    rows = peak_rows(out)
    assert [role for _, role in rows] == ["unknown", "unknown"]
    assert sorted(tof for tof, _ in rows) == [pytest.approx(VICTIM_S * 1e9, abs=0.4),
                                              pytest.approx(AGGRESSOR_S * 1e9, abs=0.4)]
    assert "roles: unknown: FLISS off" in out and "give --victim-tof" in out
    assert "  suppression S: unknown\n" in out and "S =" not in out and "S >=" not in out
    # Told where the victim is, the other peak is the aggressor's: S = 10 log10(300/500)
    status, out, err = fliss(capsys, "analyze", path, "--victim-tof", f"{VICTIM_S * 1e9}ns")
    rows = dict((role, tof) for tof, role in peak_rows(out))
    assert rows["victim"] == pytest.approx(VICTIM_S * 1e9, abs=0.4)
    assert rows["aggressor"] == pytest.approx(AGGRESSOR_S * 1e9, abs=0.4)
    s_db = float(out.split("suppression S = ")[1].split()[0])
    assert s_db == pytest.approx(10 * math.log10(300 / 500), abs=0.6)


def test_with_fliss_on_the_lone_peak_is_the_victims(tmp_path, capsys):
    path = write(tmp_path / "on.h5", [(VICTIM_S, 300)], ON)
    status, out, err = fliss(capsys, "analyze", path)
    assert (status, err) == (0, "")
    (tof, role), = peak_rows(out)
    assert role == "victim" and tof == pytest.approx(VICTIM_S * 1e9, abs=0.4)
    assert "the one peak is the victim's echo" in out
    text = float(out.split("suppression S >= ")[1].split()[0])
    # --json gives the same value, as a lower bound, and the peak's role
    status, out, err = fliss(capsys, "analyze", "--json", path)
    record, = json.loads(out)
    assert record["suppression"]["bound"] == "lower"
    assert round(record["suppression"]["value_db"], 2) == text
    assert [peak["role"] for peak in record["peaks"]] == ["victim"]
    assert "suppression_db" not in record
    assert record["settings"] == "FLISS masked Wm=6, aggressor on"


def test_with_fliss_on_several_peaks_have_unknown_roles():
    peaks = [Peak(0, 26.7e-9, 2e-9, 50.0), Peak(0, 120e-9, 2e-9, 10.0)]
    roles = assign(peaks, {**scene.configuration(pixel_bits=0), **ON})
    assert roles.roles == ("unknown", "unknown") and roles.victim is None
    assert "2 peaks stand" in roles.reason


def test_with_the_aggressor_off_every_peak_is_the_victims_and_there_is_no_s(tmp_path, capsys):
    path = write(tmp_path / "alone.h5", [(VICTIM_S, 300)], ALONE)
    status, out, err = fliss(capsys, "analyze", path)
    assert [role for _, role in peak_rows(out)] == ["victim"]
    assert "the aggressor emitter was off" in out and "no suppression to measure" in out
    assert "  suppression S: unknown\n" in out


def test_a_plain_histogram_without_settings_says_the_roles_are_unknown():
    histogram = counts([(VICTIM_S, 300), (AGGRESSOR_S, 500)]).astype(np.int64)
    result = analyze(histogram, BIN_S, shift=SHIFT)
    assert result.roles.roles == ("unknown", "unknown") and result.suppression is None
    assert result.note.startswith("unknown: the board's settings are not known")


# Wrong aggressor positions --------------------------------------------------------------------

def test_an_aggressor_position_on_the_victims_is_refused(tmp_path, capsys):
    path = write(tmp_path / "off.h5", [(VICTIM_S, 300), (AGGRESSOR_S, 500)], OFF)
    for command in (["analyze", path], ["plot", path, "-o", tmp_path / "x.png"]):
        status, out, err = fliss(capsys, *command, "--victim-tof", "26.7ns",
                                 "--aggressor-tof", "27ns")
        assert (status, out) == (1, "")
        assert err == ("fliss: error: --aggressor-tof 27ns is within 1.5 ns of --victim-tof "
                       "26.7ns: one peak cannot be the victim's and the aggressor's\n")
    assert not (tmp_path / "x.png").exists()


def test_an_aggressor_position_at_no_peak_leaves_s_unknown(tmp_path, capsys):
    # The aggressor's peak stands at 101.7 ns, --aggressor-tof says 150 ns: the old analysis
    # said "no aggressor peak above the detection threshold" and gave a lower bound.
    path = write(tmp_path / "off.h5", [(VICTIM_S, 300), (AGGRESSOR_S, 100)], OFF)
    status, out, err = fliss(capsys, "analyze", path, "--victim-tof", f"{VICTIM_S * 1e9}ns",
                             "--aggressor-tof", "150ns")
    assert status == 0
    assert [role for _, role in peak_rows(out)] == ["victim", "unknown"]
    assert f"S unknown: the peak at {AGGRESSOR_S * 1e9:.1f} ns is neither the victim's nor " \
        f"at --aggressor-tof" in out
    assert "  suppression S: unknown\n" in out
    assert "no aggressor peak above the detection threshold" not in out


def test_an_aggressor_position_on_fliss_ons_lone_peak_is_questioned(tmp_path, capsys):
    path = write(tmp_path / "on.h5", [(VICTIM_S, 300)], ON)
    status, out, err = fliss(capsys, "analyze", path, "--aggressor-tof", f"{VICTIM_S * 1e9}ns")
    assert [role for _, role in peak_rows(out)] == ["unknown"]         # the two disagree
    assert "a lone peak is the victim's; check --aggressor-tof" in out
    assert "  suppression S: unknown\n" in out


def test_captures_with_fliss_off_and_on_name_the_peak_in_both(tmp_path, capsys):
    # With FLISS off the aggressor's peak stands at 101.7 ns; with FLISS on it is spread, but a
    # tooth of what is left of it stands at 64 ns: neither capture alone can tell, yet the one
    # peak at the same time in both is the victim's.
    off = write(tmp_path / "off.h5", [(VICTIM_S, 300), (AGGRESSOR_S, 500)], OFF)
    on = write(tmp_path / "on.h5", [(VICTIM_S, 300), (64e-9, 60)], ON, seed=2)
    status, out, err = fliss(capsys, "analyze", off, on)
    assert out.count("  suppression S: unknown\n") == 2
    hint = out.splitlines()[-1]
    assert hint.startswith(f"hint: {off} (FLISS off, aggressor on) and {on} (FLISS masked "
                           f"Wm=6, aggressor on) have one peak at the same time, ")
    tof = float(hint.split("at the same time, ")[1].split()[0])
    assert tof == pytest.approx(VICTIM_S * 1e9, abs=0.4)
    assert hint.endswith(f"give --victim-tof {tof:.3f}ns")
    # Told, the analysis of both follows
    status, out, err = fliss(capsys, "analyze", off, on, "--victim-tof", f"{tof}ns")
    assert "hint" not in out and out.count("suppression S = ") == 2


# fliss plot --------------------------------------------------------------------------------

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


def test_plot_labels_the_lone_peak_with_fliss_on_as_the_victims(tmp_path, capsys, drawn):
    path = write(tmp_path / "on.h5", [(VICTIM_S, 300)], ON)
    assert fliss(capsys, "plot", path, "-o", tmp_path / "on.png")[0] == 0
    figure = drawn["on.png"]
    text, = figure.axes[0].texts
    assert text.get_text().startswith("victim ")
    assert text.xy[0] == pytest.approx(VICTIM_S * 1e9, abs=0.4)
    assert " (FLISS masked Wm=6, aggressor on): S >= " in figure.legends[0].get_texts()[0] \
        .get_text()


def test_dollars_in_titles_and_file_names_are_drawn_as_they_are(tmp_path, capsys, drawn):
    path = write(tmp_path / "cost $5 and $6.h5", [(VICTIM_S, 300)], ON)
    # (as maths, "$\foo$" is an unknown symbol: matplotlib's traceback before)
    status, out, err = fliss(capsys, "plot", path, "-o", tmp_path / "a.png", "--title",
                             r"$\foo$")
    assert (status, err) == (0, "")
    figure = drawn["a.png"]
    title = figure.axes[0].title
    label = figure.legends[0].get_texts()[0]
    # What matplotlib draws of each text (its own reading): the letters, no maths.
    assert title._preprocess_math(title.get_text()) == (r"$\foo$", False)
    assert label._preprocess_math(label.get_text()) == (
        "cost $5 and $6.h5 (FLISS masked Wm=6, aggressor on): S >= "
        + label.get_text().split(" >= ")[1], False)


def test_depth_plots_say_whether_fliss_was_on(tmp_path, drawn):
    from fliss.host.imager.report import plot_imager
    for settings, said in ((ON, "FLISS masked Wm=6, aggressor on"),
                           (OFF, "FLISS off, aggressor on")):
        path = tmp_path / f"d{settings['delay_mode']}.h5"
        with CaptureWriter(str(path), mode="depth", identity=scene.identity(),
                           configuration=scene.configuration(**settings)) as writer:
            for frame in scene.depth_frames(np.tile(scene.TRUTH_M, (2, 1))):
                writer.add_frame(frame)
        capture = read_capture(str(path))
        for frames in ("summary", "grid"):
            output = tmp_path / f"{path.stem}-{frames}.png"
            plot_imager(capture, str(output), frames=frames, quiet=True)
            assert f"({said})" in drawn[output.name]._suptitle.get_text()


def test_plot_refuses_to_replace_a_file_without_overwrite(tmp_path, capsys):
    path = write(tmp_path / "on.h5", [(VICTIM_S, 300)], ON)
    (tmp_path / "a.png").write_bytes(b"keep")
    status, out, err = fliss(capsys, "plot", path, "-o", tmp_path / "a.png")
    assert (status, out) == (1, "")
    assert err == f"fliss: error: {tmp_path / 'a.png'} exists (use --overwrite to replace it)\n"
    assert (tmp_path / "a.png").read_bytes() == b"keep"
    status, out, err = fliss(capsys, "plot", path, "-o", tmp_path / "a.png", "--overwrite")
    assert status == 0 and (tmp_path / "a.png").read_bytes()[:4] == b"\x89PNG"


def test_plot_refuses_a_range_beyond_the_histograms(tmp_path, capsys):
    path = write(tmp_path / "on.h5", [(VICTIM_S, 300)], ON)
    status, out, err = fliss(capsys, "plot", path, "-o", tmp_path / "a.png", "--range", "500ns",
                             "900ns")
    assert (status, out) == (1, "")
    assert err == ("fliss: error: --range 500 ns 900 ns: the histograms end at 409.6 ns; "
                   "nothing to draw there\n")
    assert not (tmp_path / "a.png").exists()


# fliss board's line scene ---------------------------------------------------------------------

def test_the_board_says_when_the_column_would_seldom_keep_the_walls_echo():
    from fliss.host.commands.board import column_note
    # The defaults: 60 pixels, 0.05 aggressor photons a pulse and 100 kHz of ambient light
    # each, in a window of 8192 codes of 50 ps: 60 (0.05 + 1e5 * 409.6e-9) = 5.46 photons that
    # may come after the echo; the column keeps the last, so the echo in exp(-5.46) = 0.43 %.
    note = column_note("line", "column", 0.05, 1e5)
    assert note.startswith("about 5.5 photons of aggressor and ambient light reach the column "
                           "in a laser cycle's 409.6 ns window")
    assert "the wall's echo in about 0.4 % of cycles" in note
    # The demo's light: 60 (0.02 + 1e4 * 409.6e-9) = 1.45 photons, the echo in 23 %: no note;
    # nor for a sensor with a TDC per pixel, nor for the single pixel.
    assert column_note("line", "column", 0.02, 1e4) is None
    assert column_note("line", "per_pixel", 0.05, 1e5) is None
    assert column_note("single", "column", 0.05, 1e5) is None


def test_analyze_refuses_what_it_would_ignore(tmp_path, capsys):
    histogram = write(tmp_path / "on.h5", [(VICTIM_S, 300)], ON)
    span_ns = (8192 >> SHIFT) * BIN_S * 1e9               # the histogram's bins, worked out
    depth = tmp_path / "depth.h5"
    with CaptureWriter(str(depth), mode="depth", identity=scene.identity(),
                       configuration=scene.configuration(**ON)) as writer:
        for frame in scene.depth_frames(np.tile(scene.TRUTH_M, (2, 1))):
            writer.add_frame(frame)
    import format_captures
    raw = tmp_path / "raw.h5"
    format_captures.raw_capture(raw, 500)
    cases = [
        ([str(raw), "--per-acquisition"],
         f"--per-acquisition applies to histogram captures; {raw} is a raw capture, one stream "
         f"of events with no acquisitions"),
        ([histogram, "--tolerance", "1s"],
         f"--tolerance 1s is as wide as {histogram}'s histogram (0 to {span_ns:g} ns): every "
         f"peak would be at every position"),
        ([histogram, "--aggressor-tof", "1e9s"],
         f"--aggressor-tof 1e+09 s is outside {histogram}'s histogram (0 to {span_ns:g} ns)"),
        ([histogram, "--victim-tof", f"{span_ns + 1:g}ns"],
         f"--victim-tof {span_ns + 1:g} ns is outside {histogram}'s histogram "
         f"(0 to {span_ns:g} ns)"),
        ([str(depth), "--victim-tof", "26ns"],
         f"--victim-tof applies to histogram and raw captures; {depth} is a depth capture, "
         f"analysed pixel by pixel without it"),
        ([str(depth), "--per-acquisition"],
         f"--per-acquisition applies to histogram and raw captures; {depth} is a depth "
         f"capture, analysed pixel by pixel without it"),
        # a file of another kind after a good one: refused before anything is printed
        ([histogram, str(depth), "--aggressor-tof", "100ns"],
         f"--aggressor-tof applies to histogram and raw captures; {depth} is a depth capture, "
         f"analysed pixel by pixel without it"),
    ]
    for argv, message in cases:
        status, out, err = fliss(capsys, "analyze", *argv)
        assert (status, out, err) == (1, "", f"fliss: error: {message}\n"), argv


def test_json_per_acquisition_gives_each_histograms_own_analysis(tmp_path, capsys):
    # Two histograms of different suppression: victim 4000 and aggressor 1000 photons
    # (S = +6 dB), then 1000 and 4000 (S = -6 dB); --per-acquisition --json carries both, as the
    # text does.
    path = str(tmp_path / "two.h5")
    with CaptureWriter(path, mode="histogram", identity=scene.identity(),
                       configuration=scene.configuration(pixel_bits=0, bin_shift=SHIFT,
                                                         **OFF)) as writer:
        for frame, (victim, aggressor) in enumerate([(4000, 1000), (1000, 4000)]):
            writer.add_histogram(HistogramFrame(
                frame, SHIFT, counts([(VICTIM_S, victim), (AGGRESSOR_S, aggressor)],
                                     seed=frame + 5), True, 0, 1.0))
    status, out, err = fliss(capsys, "analyze", "--json", "--per-acquisition", path,
                             "--victim-tof", f"{VICTIM_S * 1e9}ns")
    assert (status, err) == (0, "")
    record, = json.loads(out)
    first, second = record["acquisitions"]
    assert (first["frame"], second["frame"]) == (0, 1) and first["complete"]
    assert first["suppression"]["value_db"] == pytest.approx(10 * math.log10(4), abs=0.5)
    assert second["suppression"]["value_db"] == pytest.approx(-10 * math.log10(4), abs=0.5)
    assert sorted(peak["role"] for peak in second["peaks"]) == ["aggressor", "victim"]
    # Without --per-acquisition, no such key
    status, out, err = fliss(capsys, "analyze", "--json", path)
    assert "acquisitions" not in json.loads(out)[0]
