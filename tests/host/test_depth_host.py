"""Depth frames on the host: DEPTH packets assembled into DepthFrame, malformed ones counted, and
the model board's depth mode against its own histogram mode."""

import time

import numpy as np
import pytest

from fliss.hdl.protocol import PacketType, DepthHeader
from fliss.host.cli import main
from fliss.host.client import BoardClient
from fliss.host.fileformat import read_capture
from fliss.host.stream import DepthFrame, HistogramFrame, StreamAssembler
from fliss.protocol.frames import Packet
from fliss.protocol.layout import pack
from fliss.sim.models.depth import depth_frame
from fliss.protocol.depth import depth_payload
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene, line_pixels


def depth_packet(records, frame, **settings):
    settings = {**dict(first_pixel=0, pixel_bits=(len(records).bit_length() - 1), shift=9,
                       filter=4, threshold=20), **settings}
    return Packet(PacketType.DEPTH, frame, depth_payload(records, frame=frame, **settings))


def test_assembler_makes_depth_frames():
    counts = np.full((4, 16), 2)
    counts[0, 5:9] = 50                 # bins 5-8: centre 7.0 bins
    counts[1, 0] = 30                   # below the threshold of 1000 after the background
    counts[3, 12:16] = 40               # the last window: centre 14.0 bins
    records = depth_frame(counts, shift=9, filter=4, threshold=100)
    assembler = StreamAssembler()
    [frame] = assembler.add(depth_packet(records, 7, first_pixel=8, threshold=100), 1.5)
    assert isinstance(frame, DepthFrame)
    assert (frame.frame, frame.first_pixel, frame.shift, frame.pixel_bits, frame.filter,
            frame.threshold, frame.time_s) == (7, 8, 9, 2, 4, 100, 1.5)
    assert list(frame.detected) == [True, False, False, True]
    assert frame.position[0] == 7.0 and frame.position[3] == 14.0
    assert np.isnan(frame.position[1]) and np.isnan(frame.position[2])
    assert frame.background[0] == 2.0 and frame.height[0] == 4 * 48
    assert frame.height[2] == 0
    assert assembler.counters.depth_frames == 1


def test_assembler_counts_lost_and_malformed_depth_frames():
    records = depth_frame(np.zeros((1, 8), int), shift=10, filter=1, threshold=0)
    assembler = StreamAssembler()
    assert len(assembler.add(depth_packet(records, 3, shift=10), 0.0)) == 1
    assert len(assembler.add(depth_packet(records, 6, shift=10), 0.0)) == 1
    assert assembler.counters.lost_depth_frames == 2
    assert assembler.frames_ended == 7
    bad = Packet(PacketType.DEPTH, 0, pack(DepthHeader, pixel_bits=1) + bytes(9))
    assert assembler.add(bad, 0.0) == []
    assert assembler.counters.malformed == 1
    assert assembler.last_malformed == "DEPTH payload of 19 bytes, not 24 for 2 pixels"
    assert assembler.counters.depth_frames == 2


def capture(mode, seconds, **registers):
    """Frames of a model board acquiring in ``mode`` (0 histogram, 2 depth) for ``seconds``."""
    with model_board(photon_seed=5) as model, BoardClient(model.path, timeout_s=2.0) as board:
        board.write_registers({"acquisition": mode, **registers})
        board.start()
        time.sleep(seconds)
        board.stop()
        time.sleep(0.2)
        return board.take_data()


@pytest.mark.parametrize("shift, filter", [(3, 4), (6, 1)])
def test_model_board_depth_mode_equals_depth_of_its_histograms(shift, filter):
    # The same scene and photon seed, once as histograms and once as depth frames: frame k's
    # DEPTH packet holds the depth records of histogram k.
    settings = dict(bin_shift=shift, integration=400_000, depth_filter=filter,
                    depth_threshold=30)
    histograms = [f for f in capture(0, 0.4, **settings) if isinstance(f, HistogramFrame)]
    depths = [f for f in capture(2, 0.4, **settings) if isinstance(f, DepthFrame)]
    common = min(len(histograms), len(depths))
    assert common >= 3
    for histogram, depth in zip(histograms[:common - 1], depths[:common - 1]):
        assert histogram.frame == depth.frame
        expected = depth_frame(np.minimum(histogram.counts, 65535)[None], shift=shift,
                               filter=filter, threshold=30)
        assert np.array_equal(depth.records, expected)
        assert (depth.shift, depth.filter, depth.threshold) == (shift, filter, 30)
    # the scene's victim return: one strong peak, found in every full frame
    assert all(depth.detected[0] for depth in depths[:common - 1])


def _depth_capture(scene, tmp_path, capsys, *capture):
    """``fliss config --pixels 64 --bin-shift 3`` (the README's split, nothing else), then a
    depth capture, on a model board with ``scene``; (exit status, stderr, the file)."""
    with model_board(scene=scene) as model:
        port = ["--port", model.path, "--timeout", "2"]
        assert main(["-q", "config", *port, "--pixels", "64", "--bin-shift", "3"]) == 0
        status = main(["-q", "capture", *port, "--readout", "depth", "-o",
                       str(tmp_path / "d.h5"), *capture])
    out, err = capsys.readouterr()
    return status, err, read_capture(tmp_path / "d.h5")


def test_the_readme_split_detects_the_line_scene_with_default_settings(tmp_path, capsys):
    # The model board's line scene as `python -m fliss.sim.boards.model --scene line` has it:
    # a wall at 4 m, an object at 2.5 m before pixels 20 to 39; 10 ms frames by default.
    scene = Scene(distance_m=4.0, detections_per_pulse=0.05, background_hz=1e5,
                  pixels=line_pixels())
    status, err, capture = _depth_capture(scene, tmp_path, capsys, "--acquisitions", "4")
    assert (status, err) == (0, "")
    truth = np.asarray(line_pixels().distance_m)
    depth = capture.depth["depth_m"][:, :60]
    detected = capture.depth["detected"][:, :60]
    right = detected & (np.abs(depth - truth) < 0.15)
    wall = np.r_[0:20, 40:60]
    assert right[:, wall].mean() > 0.75                 # the wall, in most pixels and frames
    assert (detected & ~right).mean() < 0.03            # few false detections
    assert not capture.depth["detected"][:, 60:].any()  # nothing where there are no pixels


def test_a_depth_capture_that_detects_nothing_says_so(tmp_path, capsys):
    scene = Scene(distance_m=4.0, detections_per_pulse=1e-4, background_hz=1e2,
                  pixels=line_pixels())
    status, err, capture = _depth_capture(scene, tmp_path, capsys, "--acquisitions", "2",
                                          "--integration", "1ms")
    assert status == 0 and not capture.depth["detected"].any()
    highest = int(capture.depth["height"].max())
    # 64 pixels of 1024 bins, 1 ms: mu = 4 x 1000 / 65536 = 0.061 counts in a window, and of
    # 256 windows P(X >= 3) = 3.7e-5 <= 3.9e-5 (P(X >= 2) = 1.8e-3): a threshold of 3.
    assert err == (f"fliss: warning: no pixel detected a target in 2 depth frames: the highest "
                   f"peak was {highest} counts above the background, --depth-threshold is 3; "
                   f"try a longer --integration (more photons), a larger --depth-filter or "
                   f"--bin-shift (a wider window), or a lower --depth-threshold (more false "
                   f"detections)\n")
