"""`fliss capture --readout depth` records the sensor's geometry and `fliss export --to ply`
makes the points of its frames: on a model board seeing the line scene (a wall at 4 m, an object
at 2.5 m before pixels 20 to 39), every point lies on its pixel's line of sight at the scene's
distance, checked with trigonometry worked out here; and what cannot become points is refused
in one line."""

import numpy as np
import pytest

from fliss.host.cli import main
from fliss.host.fileformat import read_capture
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene, line_pixels

from format_captures import histogram_capture, two_echoes


def depth_capture(path, *flags, acquisitions=3):
    """A depth capture of the line scene into ``path``, with the capture's ``flags``."""
    scene = Scene(distance_m=4.0, detections_per_pulse=0.05, background_hz=1e5,
                  pixels=line_pixels())
    with model_board(scene=scene) as model:
        port = ["--port", model.path, "--timeout", "2"]
        assert main(["-q", "config", *port, "--pixels", "64", "--bin-shift", "3"]) == 0
        assert main(["-q", "capture", *port, "--readout", "depth", "--acquisitions",
                     str(acquisitions), *flags, "-o", str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def line_capture(tmp_path_factory):
    """A depth capture of the line scene, its geometry given: 20 µm pixels, a 4 mm lens."""
    return depth_capture(tmp_path_factory.mktemp("points") / "line.h5",
                         "--pitch", "20um", "--focal-length", "4mm")


def test_the_points_lie_on_their_pixels_lines_of_sight(line_capture, tmp_path, capsys):
    plyfile = pytest.importorskip("plyfile")
    capsys.readouterr()
    assert main(["export", str(line_capture), "--to", "ply", "-o", str(tmp_path / "l.ply")]) == 0
    out, err = capsys.readouterr()
    assert err == ""                        # the lens is recorded: nothing assumed
    capture = read_capture(line_capture)
    detected = capture.depth["detected"]
    assert f"{int(detected.sum())} points of 3 frames" in out
    vertex = plyfile.PlyData.read(str(tmp_path / "l.ply"))["vertex"]
    truth = np.asarray(line_pixels().distance_m)
    pixel = np.asarray(vertex["pixel"]).astype(int)
    assert (pixel < 60).all() and len(pixel) > 100
    # Within the depth engine's error of the scene's distance, along the ray
    assert np.mean(np.abs(vertex["range"] - truth[pixel]) < 0.15) > 0.95
    # A column of 64 addresses: the optical centre midway, row 31.5, so pixel p looks
    # atan((p - 31.5) * 20 µm / 4 mm) off the axis, in the y-z plane
    angle = np.arctan((pixel - 31.5) * 20e-6 / 4e-3)
    np.testing.assert_allclose(vertex["x"], 0, atol=1e-6)
    np.testing.assert_allclose(np.arctan2(vertex["y"], vertex["z"]), angle, atol=1e-5)
    np.testing.assert_allclose(np.hypot(vertex["y"], vertex["z"]), vertex["range"], rtol=1e-5)
    # The object stands out: its points are nearer than the wall's
    assert np.median(vertex["z"][(pixel >= 20) & (pixel < 40)]) < 2.6 < 3.9 < \
        np.median(vertex["z"][(pixel < 20) | (pixel >= 40)])


def test_a_flag_overrides_the_recorded_geometry(line_capture, tmp_path, capsys):
    plyfile = pytest.importorskip("plyfile")
    assert main(["-q", "export", str(line_capture), "--to", "ply", "-o", str(tmp_path / "g.ply"),
                 "--pixel-layout", "grid:8"]) == 0
    vertex = plyfile.PlyData.read(str(tmp_path / "g.ply"))["vertex"]
    pixel = np.asarray(vertex["pixel"]).astype(int)
    # Eight pixels a row: pixel p at column p % 8; the centre at column 3.5 (recorded pitch
    # and lens)
    np.testing.assert_allclose(np.arctan2(vertex["x"], vertex["z"]),
                               np.arctan((pixel % 8 - 3.5) * 20e-6 / 4e-3), atol=1e-5)


def test_an_unknown_lens_is_said(tmp_path, capsys):
    pytest.importorskip("plyfile")
    path = tmp_path / "d.h5"
    with model_board() as model:
        port = ["--port", model.path, "--timeout", "2"]
        assert main(["-q", "capture", *port, "--readout", "depth", "--acquisitions", "1",
                     "-o", str(path)]) == 0
    capsys.readouterr()
    assert main(["-q", "export", str(path), "--to", "ply", "-o", str(tmp_path / "d.ply")]) == 0
    err = capsys.readouterr().err
    assert err.startswith("fliss: warning: the lens is not known (the capture assumed it, and "
                          "no --focal-length or --fov is given): the points assume a 2.5 mm lens")
    assert err.count("\n") == 1


def test_what_holds_no_depth_frames_is_refused(tmp_path, capsys):
    histogram_capture(tmp_path / "h.h5", [two_echoes(1)])
    assert main(["export", str(tmp_path / "h.h5"), "--to", "las", "-o",
                 str(tmp_path / "h.las")]) == 1
    assert capsys.readouterr().err == (
        f"fliss: error: {tmp_path / 'h.h5'}: a histogram capture has no depth frames: a point "
        f"cloud (--to las) is made of a depth capture's frames (fliss capture --readout "
        f"depth)\n")
    assert not (tmp_path / "h.las").exists()
    assert main(["export", str(tmp_path / "h.h5"), "--to", "ptu", "-o", str(tmp_path / "h.ptu"),
                 "--pitch", "20um"]) == 1
    assert capsys.readouterr().err.startswith(
        "fliss: error: --pitch: the sensor's geometry places a depth capture's points: it is "
        "for --to ply, pcd, las, mcap, mcap-ros2, not --to ptu")
    assert main(["export", str(tmp_path / "missing.h5"), "--to", "ply", "-o",
                 str(tmp_path / "m.ply")]) == 1
    assert "missing.h5" in capsys.readouterr().err


def test_a_bad_geometry_flag_is_refused_before_the_board(tmp_path, capsys):
    assert main(["capture", "--port", str(tmp_path / "no-board"), "--readout", "depth",
                 "--fov", "200deg", "-o", str(tmp_path / "d.h5")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("fliss: error: --fov 200deg: ") and err.count("\n") == 1
    assert not (tmp_path / "d.h5").exists()


def test_the_view_shows_a_grids_depth_as_an_image(line_capture, tmp_path, monkeypatch):
    """`fliss view FILE` of a depth capture takes the image's shape from the geometry it
    records: eight rows of eight for a grid 8 wide; a profile (no shape) for the column."""
    pytest.importorskip("bokeh", reason="the live view needs Bokeh (pip install 'fliss[view]')")
    import fliss.host.commands.view as view

    shown = []
    monkeypatch.setattr(view, "_replay", lambda capture, feed, args, limit: shown.append(
        feed.setup.shape) or 0)
    grid = depth_capture(tmp_path / "grid.h5", "--pixel-layout", "grid:8", acquisitions=1)
    assert main(["view", str(grid)]) == 0
    assert main(["view", str(line_capture)]) == 0
    assert main(["view", str(grid), "--shape", "4x16"]) == 0
    assert shown == [(8, 8), None, (4, 16)]
