"""The imager in the Python API (Board.acquire_image, Board.acquire_depth), a single-pixel
image capture on the model board, and the demo's FLISS off/on comparison (issue 17)."""

import numpy as np
import pytest

import fliss
from fliss.host.board import Board
from fliss.host.cli import main
from fliss.host.imager.demo import (compare_profiles, draw_profiles, run_on_board,
                                    summary_lines)
from fliss.host.errors import SettingsError
from fliss.host.fileformat import read_capture
from fliss.host.imager.results import DepthFrames, Images
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene, line_pixels

import imager_frames as scene
from imager_frames import C, FIRST, TRUTH_M, FakeClient


def test_acquire_image_gives_frames_pixels_bins():
    frames = scene.histogram_frames(3)
    board = Board(FakeClient(frames, scene.configuration(acquisition=1)))
    images = board.acquire_image(2)
    assert isinstance(images, Images) and fliss.Images is Images
    assert board.client.registers["acquisition"] == 0       # switched to histogram readout
    assert images.counts.shape == (2, 8, 1024)
    assert np.array_equal(images.counts[1], frames[1].counts.reshape(8, 1024))
    assert list(images.pixels) == list(FIRST + np.arange(8))
    assert images.time_s[[0, 1]] == pytest.approx([200e-12, 600e-12])
    assert list(images.frames) == [0, 1] and images.complete.all()
    assert images.settings["pixels"] == 8 and images.bin_s == pytest.approx(400e-12)
    assert np.array_equal(images.intensity, images.counts.sum(axis=2))


def test_acquire_depth_gives_metres():
    depths = np.tile(TRUTH_M, (4, 1))
    depths[1, 0] = np.nan
    board = Board(FakeClient(scene.depth_frames(depths), scene.configuration()))
    result = board.acquire_depth(4)
    assert isinstance(result, DepthFrames) and fliss.DepthFrames is DepthFrames
    assert board.client.registers["acquisition"] == 2
    assert np.allclose(result.depth_m, depths, equal_nan=True, atol=1e-6)
    assert np.allclose(result.tof_s, 2 * depths / C, equal_nan=True)
    assert result.detected.sum() == 31 and result.detection_rate[0] == 0.75
    assert list(result.pixels) == list(FIRST + np.arange(8))
    with pytest.raises(SettingsError, match="n must be at least 1"):
        board.acquire_depth(0)


def test_configure_refuses_a_split_for_the_boards_bank():
    board = Board(FakeClient([], scene.configuration(pixel_bits=0, bin_shift=0,
                                                     first_pixel=0)))
    with pytest.raises(SettingsError, match=r"^pixels=64 with bin_shift=0 .*\(bin_shift=3\)"):
        board.configure(pixels=64)
    assert board.client.written == []                           # nothing written
    board.configure(pixels=64, bin_shift=3, depth_threshold=7)
    assert board.client.written == [{"bin_shift": 3, "pixel_bits": 6, "depth_threshold": 7}]


def test_single_pixel_image_capture_on_the_model_board(tmp_path, capsys):
    # The model board of main histograms every address as pixel 0: --pixel 0 (the lead may
    # move it to another address once the model board keeps first_pixel).
    with model_board(scene=Scene(detections_per_pulse=0.1, background_hz=2e5)) as model:
        status = main(["-q", "capture", "--port", model.path, "--timeout", "2", "--readout",
                       "image", "--pixel", "0", "--integration", "1ms", "--bin-shift", "2",
                       "--acquisitions", "2", "-o", str(tmp_path / "one.h5")])
    out, err = capsys.readouterr()
    assert (status, out, err) == (0, "", "")
    saved = read_capture(tmp_path / "one.h5")
    assert saved.mode == "image" and saved.histograms.shape == (2, 1, 2048)
    assert list(saved.pixels) == [0] and saved.configuration["pixel_bits"] == 0
    assert saved.complete.all() and saved.histograms.sum() > 0


def _depths(truth, ghosts, frames=6, seed=2):
    # Depth frames of the scene with 1 cm of noise; ``ghosts`` maps pixel -> a ghost depth
    # that replaces the truth in most frames (an aggressor's echo).
    rng = np.random.default_rng(seed)
    depths = truth + rng.normal(0, 0.01, (frames, len(truth)))
    for pixel, ghost in ghosts.items():
        depths[: frames - 1, pixel] = ghost
    return depths


def test_demo_comparison_counts_the_wrong_pixels(tmp_path):
    off = _depths(TRUTH_M, {1: 11.2, 6: 11.2})          # ghosts 75 ns after the victim
    off[:, 7] = np.nan                                    # and a pixel that never sees it
    on = _depths(TRUTH_M, {})
    comparison = compare_profiles(off, on, TRUTH_M, FIRST + np.arange(8))
    assert list(np.flatnonzero(comparison.off.wrong)) == [1, 6]
    assert list(np.flatnonzero(comparison.off.missing)) == [7]
    assert not comparison.on.wrong.any() and not comparison.on.missing.any()
    # 10 of the 42 detections off are ghosts (5 frames x 2 pixels).
    assert comparison.off.wrong_frames == pytest.approx(10 / 42)
    lines = summary_lines(comparison)
    assert lines[0].startswith("FLISS off: 2 of 8 pixels at a wrong depth (more than 0.15 m "
                               "from the scene) (pixels 9, 14), 1 without a target")
    assert lines[1].startswith("FLISS on: 0 of 8 pixels at a wrong depth")
    draw_profiles(comparison, str(tmp_path / "profiles.png"), title="line scene")
    assert (tmp_path / "profiles.png").read_bytes()[:4] == b"\x89PNG"


def test_demo_comparison_takes_depth_frames_and_refuses_a_wrong_truth():
    frames = scene.depth_frames(np.tile(TRUTH_M, (3, 1)))
    settings = Board(FakeClient([], scene.configuration())).settings
    from fliss.host.imager.results import depth_from_frames
    depth = depth_from_frames(frames, settings)
    comparison = compare_profiles(depth, depth, TRUTH_M)
    assert list(comparison.pixels) == list(FIRST + np.arange(8))
    assert comparison.on.depth_m == pytest.approx(TRUTH_M, abs=1e-6)
    with pytest.raises(ValueError, match="^depth frames of 8 pixels against a true profile of 4$"):
        compare_profiles(depth, depth, TRUTH_M[:4])


def test_demo_runs_on_a_board(tmp_path):
    off = _depths(TRUTH_M, {4: 11.2}, frames=5)
    on = _depths(TRUTH_M, {}, frames=5, seed=3)
    frames = scene.depth_frames(np.concatenate([off, on]))
    board = Board(FakeClient(frames, scene.configuration()))
    comparison = run_on_board(board, TRUTH_M, str(tmp_path / "demo.png"), frames=5,
                              settings={"pixels": 8, "first_pixel": FIRST, "bin_shift": 3})
    writes = board.client.written
    assert {"delay_mode": 0} in writes and {"delay_mode": 2, "mask_width": 6} in writes
    assert list(np.flatnonzero(comparison.off.wrong)) == [4] and not comparison.on.wrong.any()
    assert (tmp_path / "demo.png").exists()


def test_frames_of_another_split_are_left_out_and_acquire_refuses_pixels():
    stale = scene.histogram_frames(1, first=0)             # sent before the settings changed
    frames = stale + scene.histogram_frames(2, start=1)
    board = Board(FakeClient(frames, scene.configuration()))
    images = board.acquire_image(2)
    assert list(images.frames) == [1, 2] and list(images.pixels) == list(FIRST + np.arange(8))
    with pytest.raises(SettingsError, match=r"^the board histograms 8 pixels a frame: use "
                                            r"acquire_image\(n\), or configure\(pixels=1\)$"):
        board.acquire(1)


def test_acquire_depth_says_when_nothing_is_detected(caplog):
    # Hardly a photon: no pixel reaches the threshold, and one warning says so and what to try.
    dim = Scene(detections_per_pulse=1e-4, background_hz=1e2, pixels=line_pixels())
    with model_board(scene=dim) as model, fliss.connect(model.path, timeout_s=2.0) as board:
        board.configure(pixels=64, bin_shift=3, integration="1ms")
        depth = board.acquire_depth(2)
    assert not depth.detected.any()
    # (64 pixels of 1024 bins, 1 ms: the threshold 3 of tests/host/test_depth_host.py)
    assert [record.getMessage() for record in caplog.records] == [
        f"no pixel detected a target in 2 depth frames: the highest peak was "
        f"{int(depth.height.max())} counts above the background, depth_threshold is 3; try a "
        f"longer integration (more photons), a larger depth_filter or bin_shift (a wider "
        f"window), or a lower depth_threshold (more false detections)"]
