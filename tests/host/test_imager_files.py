"""Image and depth captures (issue 17): HDF5 round trip with named axes, the capture loop with
frames of the imager, `fliss analyze` and `fliss plot` of them, against a synthetic line scene
whose depths are known (tests/host/imager_frames.py)."""

import json
import math
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from fliss.host.acquisition import capture
from fliss.host.cli import main
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.host.imager.analysis import capture_table, depth_table, image_table

import imager_frames as scene
from imager_frames import C, FIRST, LSB_S, SHIFT, TRUTH_M, FakeClient


BIN_S = LSB_S * (1 << SHIFT)
PIXELS = FIRST + np.arange(len(TRUTH_M))


def write_image(path, frames, **changes):
    with CaptureWriter(str(path), mode="image", identity=scene.identity(),
                       configuration=scene.configuration(**changes)) as writer:
        return [writer.add_frame(frame) for frame in frames]


def write_depth(path, frames):
    with CaptureWriter(str(path), mode="depth", identity=scene.identity(),
                       configuration=scene.configuration()) as writer:
        return [writer.add_frame(frame) for frame in frames]


def fliss(capsys, *argv):
    status = main([str(part) for part in argv])
    return (status, *capsys.readouterr())


def test_image_file_round_trip_with_named_axes(tmp_path):
    frames = scene.histogram_frames(3)
    frames[1].complete, frames[1].missing_bins = False, 12
    assert write_image(tmp_path / "a.h5", frames) == [True, True, True]
    saved = read_capture(tmp_path / "a.h5")
    assert (saved.mode, saved.problems, saved.attrs["format_version"]) == ("image", [], 3)
    assert saved.histograms.shape == (3, 8, 1024)
    for row, frame in zip(saved.histograms, frames):
        assert np.array_equal(row.ravel(), frame.counts)     # pixel-major, as sent
    assert list(saved.pixels) == list(PIXELS)
    assert list(saved.complete) == [True, False, True] and list(saved.frames) == [0, 1, 2]
    assert saved.bin_s == pytest.approx(400e-12)
    with h5py.File(tmp_path / "a.h5", "r") as f:
        counts = f["image/counts"]
        assert [dim.label for dim in counts.dims] == ["frame", "pixel", "bin"]
        assert counts.attrs["axes"] == "frame,pixel,bin"
        assert list(counts.dims[1][0][()]) == list(PIXELS)
        # Bin b's centre: (b + 0.5) x 400 ps.
        assert counts.dims[2][0][()][[0, 10]] == pytest.approx([200e-12, 4.2e-9])
        assert list(counts.dims[0][0][()]) == [0, 1, 2]


def test_image_file_refuses_frames_of_another_split(tmp_path):
    good = scene.histogram_frames(1)[0]
    other = scene.histogram_frames(1, first=0)[0]             # another first pixel
    wide = scene.histogram_frames(1, shift=4)[0]                # another bin width
    assert write_image(tmp_path / "a.h5", [other, good, wide]) == [False, True, False]
    assert read_capture(tmp_path / "a.h5").histograms.shape == (1, 8, 1024)


def test_depth_file_round_trip(tmp_path):
    depths = np.tile(TRUTH_M, (4, 1))
    depths[2, 3] = np.nan                                       # pixel 11 missed in frame 2
    assert all(write_depth(tmp_path / "d.h5", scene.depth_frames(depths)))
    saved = read_capture(tmp_path / "d.h5")
    assert saved.mode == "depth" and list(saved.pixels) == list(PIXELS)
    assert saved.depth["depth_m"].shape == (4, 8)
    assert np.allclose(saved.depth["depth_m"], depths, equal_nan=True, atol=1e-6)
    assert saved.depth["detected"].sum() == 31
    with h5py.File(tmp_path / "d.h5", "r") as f:
        for name in ("position", "depth_m", "height", "background", "detected"):
            assert [dim.label for dim in f["depth"][name].dims] == ["frame", "pixel"]
            assert f["depth"][name].attrs["axes"] == "frame,pixel"
    rows = depth_table(saved.depth, saved.pixels, saved.complete)
    assert [row.depth_m for row in rows] == pytest.approx(list(TRUTH_M), abs=1e-6)
    assert [row.detection_rate for row in rows] == [1, 1, 1, 0.75, 1, 1, 1, 1]
    assert all(row.detected for row in rows)


def test_image_analysis_finds_each_pixels_depth():
    frames = scene.histogram_frames(5, seed=7)
    total = np.sum([frame.image for frame in frames], axis=0)
    rows = image_table(total, PIXELS, BIN_S, SHIFT, frames=5)
    assert [row.address for row in rows] == list(PIXELS)
    assert all(row.detected for row in rows)
    # ToF 2 d / c: 26.69 ns at 4 m, 16.68 ns at 2.5 m; within 3 cm (0.2 ns, half a bin).
    assert [row.depth_m for row in rows] == pytest.approx(list(TRUTH_M), abs=0.03)
    assert [row.tof_s for row in rows] == pytest.approx(list(2 * TRUTH_M / C), abs=0.2e-9)
    # Background 0.5 counts per bin per frame, 5 frames.
    assert [row.background for row in rows] == pytest.approx([2.5] * 8, rel=0.1)


def test_image_analysis_says_when_a_pixel_sees_nothing():
    means = scene.expected_counts()
    means[2] = 0.5                                          # pixel 10: background only
    counts = np.random.default_rng(3).poisson(means * 5)
    rows = image_table(counts, PIXELS, BIN_S, SHIFT, frames=5)
    assert [row.detected for row in rows] == [True, True, False, True, True, True, True, True]
    assert math.isnan(rows[2].depth_m) and rows[2].background == pytest.approx(2.5, rel=0.1)


def test_capture_of_images_and_depth_frames(tmp_path):
    registers = scene.configuration(acquisition=1)
    client = FakeClient(scene.histogram_frames(4), registers)
    result = capture(client, str(tmp_path / "i.h5"), mode="image", acquisitions=3)
    assert result.complete and result.histograms == 3 and result.what == "3 images"
    assert client.written[0]["acquisition"] == 0                # histogram readout
    saved = read_capture(tmp_path / "i.h5")
    assert saved.histograms.shape == (3, 8, 1024) and saved.attrs["complete"]
    rows = capture_table(saved)
    assert [row.depth_m for row in rows] == pytest.approx(list(TRUTH_M), abs=0.03)

    frames = scene.depth_frames(np.tile(TRUTH_M, (5, 1)))
    del frames[1]                                               # lost on the link
    client = FakeClient(frames, registers)
    result = capture(client, str(tmp_path / "d.h5"), mode="depth", acquisitions=3)
    assert client.written[0]["acquisition"] == 2
    assert result.histograms == 3 and result.lost_histograms == 1
    saved = read_capture(tmp_path / "d.h5")
    assert list(saved.frames) == [0, 1, 2] and list(saved.complete) == [True, False, True]
    assert not saved.depth["detected"][1].any()
    assert saved.counters["stream"]["lost_rows"] == 1


def test_analyze_prints_a_table_and_json(tmp_path, capsys):
    write_image(tmp_path / "a.h5", scene.histogram_frames(4))
    status, out, err = fliss(capsys, "analyze", tmp_path / "a.h5")
    assert (status, err) == (0, "")
    lines = out.splitlines()
    assert "image capture, 8 pixels (8 to 15), 4 complete frames of 4" in lines[0]
    assert lines[1] == "  settings: FLISS mseq L=6, aggressor off"      # the reset values
    del lines[1]
    assert lines[1].split() == ["pixel", "depth", "(m)", "ToF", "(ns)", "height", "background",
                                "detected"]
    row = lines[2 + 3].split()                                 # pixel 11: the object
    assert row[0] == "11" and float(row[1]) == pytest.approx(2.5, abs=0.03)
    assert row[-1] == "yes" and lines[-1] == "  8 of 8 pixels detected a target"

    write_depth(tmp_path / "d.h5", scene.depth_frames(np.tile(TRUTH_M, (2, 1))))
    status, out, err = fliss(capsys, "analyze", "--json", tmp_path / "a.h5", tmp_path / "d.h5")
    assert (status, err) == (0, "")
    image, depth = json.loads(out)
    assert image["mode"] == "image" and depth["mode"] == "depth"
    assert [pixel["address"] for pixel in depth["pixels"]] == list(PIXELS)
    assert [pixel["depth_m"] for pixel in image["pixels"]] == pytest.approx(list(TRUTH_M),
                                                                            abs=0.03)
    assert [pixel["detection_rate"] for pixel in depth["pixels"]] == [1.0] * 8


def test_plots_are_written(tmp_path, capsys):
    write_image(tmp_path / "a.h5", scene.histogram_frames(3))
    write_depth(tmp_path / "d.h5", scene.depth_frames(np.tile(TRUTH_M, (3, 1))))
    runs = [("a.h5", "a.png", []), ("a.h5", "grid.png", ["--frames", "grid"]),
            ("d.h5", "d.png", ["--shape", "2x4"]), ("d.h5", "d.gif", ["--frames", "animation"]),
            ("d.h5", "outfile", [])]        # a PNG under the very name given
    for source, output, extra in runs:
        status, out, err = fliss(capsys, "plot", tmp_path / source, "-o", tmp_path / output,
                                 *extra)
        assert (status, err) == (0, ""), (output, err)
        assert out == f"wrote {tmp_path / output}\n"
        head = (tmp_path / output).read_bytes()[:6]
        assert head in (b"GIF89a", b"GIF87a") if output.endswith(".gif") else \
            head.startswith(b"\x89PNG")
    assert not (tmp_path / "outfile.png").exists()


@pytest.mark.parametrize("extra, message", [
    (["--shape", "3x3"], "--shape 3x3: 3 x 3 is not the capture's 8 pixels"),
    (["--shape", "big"], "--shape big: give ROWSxCOLUMNS"),
    (["--frames", "animation"], "--frames animation writes a GIF"),
])
def test_plot_refusals(tmp_path, capsys, extra, message):
    write_depth(tmp_path / "d.h5", scene.depth_frames(np.tile(TRUTH_M, (2, 1))))
    status, out, err = fliss(capsys, "plot", tmp_path / "d.h5", "-o", tmp_path / "x.png", *extra)
    assert status == 1 and out == "" and len(err.splitlines()) == 1
    assert err.startswith("fliss: error: ") and message in err
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("extra", [[], ["--frames", "grid"], ["--shape", "2x4"]])
def test_a_depth_plot_of_nothing_detected_says_so(tmp_path, capsys, monkeypatch, extra):
    # No pixel detected a target in any frame: each depth panel says so, instead of empty axes
    # from -0.04 to 0.04 m.
    from matplotlib.figure import Figure
    write_depth(tmp_path / "d.h5", scene.depth_frames(np.full((2, 8), np.nan)))
    drawn = []
    save = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda figure, *args, **kwargs: (
        drawn.append([[text.get_text() for text in axis.texts] for axis in figure.axes]),
        save(figure, *args, **kwargs)))
    status, out, err = fliss(capsys, "plot", tmp_path / "d.h5", "-o", tmp_path / "d.png", *extra)
    assert (status, err) == (0, "")
    # (one depth panel, or one per frame in the grid)
    panels = 2 if extra[:1] == ["--frames"] else 1
    assert [texts for texts in drawn[0] if texts] == [["no pixel detected a target"]] * panels


@pytest.mark.parametrize("name, kind", [("d.h5", "a depth"), ("a.h5", "an image")])
def test_imager_captures_are_plotted_one_at_a_time(tmp_path, capsys, name, kind):
    write_image(tmp_path / "a.h5", scene.histogram_frames(1))
    write_depth(tmp_path / "d.h5", scene.depth_frames(np.tile(TRUTH_M, (1, 1))))
    other = "a.h5" if name == "d.h5" else "d.h5"
    status, out, err = fliss(capsys, "plot", tmp_path / name, tmp_path / other,
                             "-o", tmp_path / "x.png")
    assert (status, out, err) == (1, "", f"fliss: error: {tmp_path / name} is {kind} capture: "
                                         f"plot one image or depth capture at a time\n")


def test_a_damaged_image_file_is_refused_in_one_line(tmp_path, capsys):
    write_image(tmp_path / "a.h5", scene.histogram_frames(1))
    with h5py.File(tmp_path / "a.h5", "r+") as f:
        del f["image/frame"]
    status, out, err = fliss(capsys, "analyze", tmp_path / "a.h5")
    assert status == 1 and len(err.splitlines()) == 1
    assert "damaged or not written by fliss (no /image/frame)" in err


@pytest.mark.parametrize("mode", ["image", "depth"])
def test_a_killed_writer_leaves_every_flushed_frame(tmp_path, mode):
    # A writer killed (os._exit: no close, as SIGKILL) after a flush: the frames flushed are
    # read back whole, with the SWMR warning, and the axes are there.
    path = tmp_path / f"{mode}.h5"
    script = f"""
import os, sys
sys.path.insert(0, {str(Path(__file__).parent)!r})
import numpy as np
import imager_frames as scene
from fliss.host.fileformat import CaptureWriter
writer = CaptureWriter({str(path)!r}, mode={mode!r}, identity=scene.identity(),
                       configuration=scene.configuration())
frames = scene.histogram_frames(4) if {mode!r} == "image" else \\
    scene.depth_frames(np.tile(scene.TRUTH_M, (4, 1)))
for frame in frames[:3]:
    writer.add_frame(frame)
writer.flush()
writer.add_frame(frames[3])
os._exit(9)
"""
    process = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                             timeout=120)
    assert process.returncode == 9, process.stderr
    saved = read_capture(path)
    assert saved.mode == mode and len(saved.frames) >= 3
    assert saved.problems and "never closed it" in saved.problems[0]
    assert list(saved.pixels) == list(PIXELS)
    if mode == "image":
        assert np.array_equal(saved.histograms[:3].reshape(3, -1),
                              [frame.counts for frame in scene.histogram_frames(3)])
    else:
        assert np.allclose(saved.depth["depth_m"][:3], np.tile(TRUTH_M, (3, 1)))


def test_analyze_json_of_a_histogram_capture(tmp_path, capsys):
    # One pixel's histogram of the scene at 4 m (ToF 26.69 ns), as a plain histogram capture.
    frame = scene.histogram_frames(1, truth_m=TRUTH_M[:1])[0]
    with CaptureWriter(str(tmp_path / "h.h5"), mode="histogram", identity=scene.identity(),
                       configuration=scene.configuration(pixel_bits=0)) as writer:
        assert writer.add_histogram(frame)
    status, out, err = fliss(capsys, "analyze", "--json", tmp_path / "h.h5")
    assert (status, err) == (0, "")
    record, = json.loads(out)
    assert record["mode"] == "histogram" and record["counts"] == int(frame.counts.sum())
    assert record["peaks"][0]["tof_s"] == pytest.approx(2 * 4.0 / C, abs=0.2e-9)


def test_a_histogram_capture_of_several_pixels_is_saved_per_pixel(tmp_path):
    client = FakeClient(scene.histogram_frames(2), scene.configuration())
    result = capture(client, str(tmp_path / "h.h5"), mode="histogram", acquisitions=2)
    assert result.mode == "image" and result.what == "2 images"
    assert read_capture(tmp_path / "h.h5").histograms.shape == (2, 8, 1024)
