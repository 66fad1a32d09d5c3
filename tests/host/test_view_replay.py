"""The pace of ``fliss view FILE`` (:class:`~fliss.host.view.replay.Replay`), on a clock of the
test's own: every frame handed at its time, a loop's rounds one after the other (issue 41: a
2-frame file looped at 68 000 frames a second), never more than ``MAX_RATE_HZ`` a second."""

import numpy as np
import pytest

from fliss.hdl.registers import defaults
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.host.stream import HistogramFrame
from fliss.host.view.feed import Feed, Setup
from fliss.host.view.replay import DEFAULT_STEP_S, MAX_RATE_HZ, Replay

CLOCK_HZ = 80_000_000


def capture_of(path, times_s, integration_cycles):
    """A histogram capture of ``len(times_s)`` frames received at ``times_s``."""
    configuration = defaults(CLOCK_HZ)
    configuration["integration"] = integration_cycles
    with CaptureWriter(str(path), mode="histogram", configuration=configuration,
                       identity={"clock_hz": CLOCK_HZ, "protocol": 3,
                                 "gateware_version": "0.1"}) as writer:
        for index, time_s in enumerate(times_s):
            writer.add_histogram(HistogramFrame(index, 0, np.full(8192, index, np.uint32), True,
                                                0, time_s))
    return read_capture(path)


class Clock:
    """Time that passes only in ``sleep``; stops the replay at ``until`` seconds."""

    def __init__(self, until):
        self.now, self.until = 0.0, until

    def __call__(self):
        return self.now

    def sleep(self, seconds):
        assert seconds > 0
        self.now += seconds
        return self.now >= self.until


class Handed(Feed):
    """A feed that notes when each frame was handed to it."""

    def __init__(self, setup, clock):
        super().__init__(setup)
        self.clock, self.times, self.frames = clock, [], []

    def add(self, item):
        self.times.append(self.clock())
        self.frames.append(item.frame)
        super().add(item)


def replayed(capture, until, **options):
    clock = Clock(until)
    feed = Handed(Setup.of_capture(capture), clock)
    replay = Replay(capture, feed, clock=clock, sleep=clock.sleep, **options)
    replay.run()
    return replay, feed


def test_a_loop_goes_round_at_the_integration_time(tmp_path):
    # 2 frames of 10 ms received at the same moment: a frame each 10 ms, round after round.
    capture = capture_of(tmp_path / "two.h5", [5.0, 5.0], 800_000)
    replay, feed = replayed(capture, 1.0, loop=True)
    assert len(feed.times) == 100
    np.testing.assert_allclose(feed.times, np.arange(100) * 0.01, atol=1e-9)
    assert feed.frames == [0, 1] * 50 and replay.rounds == 50 and replay.slowed == 1


def test_a_file_is_played_at_its_receive_times_divided_by_speed(tmp_path):
    capture = capture_of(tmp_path / "three.h5", [100.0, 100.3, 100.4], 800_000)
    replay, feed = replayed(capture, 1.9, loop=True, speed=2)
    # offsets 0, 0.15, 0.2 s; a round is 0.3 s (the last frame gets the mean gap, 0.2 s / 2)
    rounds = np.arange(8)[:, np.newaxis] * 0.3
    expected = (rounds + [0.0, 0.15, 0.2]).ravel()
    np.testing.assert_allclose(feed.times, expected[expected < 1.9], atol=1e-9)


def test_once_without_loop_and_what_the_feed_is_told(tmp_path):
    capture = capture_of(tmp_path / "two.h5", [5.0, 5.0], 800_000)
    replay, feed = replayed(capture, 100.0)
    np.testing.assert_allclose(feed.times, [0.0, 0.01])
    assert feed.state == "replayed 2 frames" and replay.rounds == 1


def test_frames_faster_than_the_most_a_second_are_slowed_to_it(tmp_path):
    # 2 frames of 1 µs: 2 000 000 a second asked, MAX_RATE_HZ given.
    capture = capture_of(tmp_path / "fast.h5", [5.0, 5.0], 80)
    replay, feed = replayed(capture, 0.5, loop=True)
    assert replay.slowed == pytest.approx((2 / MAX_RATE_HZ) / (2 * 1e-6))
    count = int(0.5 * MAX_RATE_HZ)
    np.testing.assert_allclose(feed.times, np.arange(count) / MAX_RATE_HZ, atol=1e-9)


def test_a_file_without_times_or_integration_gets_the_default_step(tmp_path):
    capture = capture_of(tmp_path / "bare.h5", [0.0, 0.0], 0)
    capture.attrs.pop("integration_s", None)
    replay, feed = replayed(capture, 1.0, loop=True)
    np.testing.assert_allclose(feed.times, np.arange(10) * DEFAULT_STEP_S, atol=1e-9)


@pytest.mark.parametrize("speed", [0, -1, float("inf"), float("nan")])
def test_a_speed_that_is_not_a_pace_is_refused(tmp_path, speed):
    capture = capture_of(tmp_path / "two.h5", [5.0, 5.0], 800_000)
    with pytest.raises(ValueError, match="speed must be positive and finite"):
        Replay(capture, Feed(Setup.of_capture(capture)), speed=speed)
