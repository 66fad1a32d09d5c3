"""Depth frames on the host: DEPTH packets assembled into DepthFrame, malformed ones counted, and
the model board's depth mode against its own histogram mode."""

import time

import numpy as np
import pytest

from fliss.hdl.protocol import PacketType, DepthHeader
from fliss.host.client import BoardClient
from fliss.host.stream import DepthFrame, HistogramFrame, StreamAssembler
from fliss.protocol.frames import Packet
from fliss.protocol.layout import pack
from fliss.sim.models.depth import depth_frame
from fliss.protocol.depth import depth_payload
from fliss.sim.boards.model import model_board


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
