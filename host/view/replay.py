"""A capture file played back into a :class:`~fliss.host.view.feed.Feed` (``fliss view
FILE``): its frames (or raw event batches) at the pace they were captured, times ``speed``, on
a thread of their own."""

import math
import threading
import time

import numpy as np

from ..kinds import of_capture
from .feed import BOARD_DROPS, Feed


__all__ = ["MAX_RATE_HZ", "DEFAULT_STEP_S", "items_of", "schedule", "Replay"]


def items_of(capture):
    """The items a board sent for ``capture`` (a :class:`~fliss.host.fileformat.Capture`),
    as the stream assembler makes them: histogram frames, depth frames, or the raw events cut
    into as many batches as the file records."""
    return of_capture(capture).replay(capture)


#: The most items a replay hands the view a second: a file whose frames came faster (times
#: ``speed``) is played slower than it was captured, by :attr:`Replay.slowed`; the page redraws
#: some ten times a second, and the sum of the frames takes every one.
MAX_RATE_HZ = 1000.0

#: Seconds per frame of a file that records neither its frames' receive times nor an
#: integration time (a PTU or Photon-HDF5 file's one histogram).
DEFAULT_STEP_S = 0.1


def schedule(items, integration_s: float, speed: float = 1.0):
    """When each of ``items`` is due in a round of the replay: ``(offsets, round_s,
    slowed)``, seconds from the round's start, the round's length (the next round starts
    then) and the factor by which :data:`MAX_RATE_HZ` slowed it (1: not at all).

    The items' own receive times (``time_s``) when they grow through the file, the last one
    given the mean gap before it; else one per ``integration_s`` (or :data:`DEFAULT_STEP_S`);
    all divided by ``speed``."""
    count = len(items)
    stamps = np.array([item.time_s for item in items], dtype=float)
    if count > 1 and np.all(np.diff(stamps) >= 0) and stamps[-1] > stamps[0]:
        offsets = stamps - stamps[0]
        step = offsets[-1] / (count - 1)
    else:
        step = integration_s if integration_s > 0 else DEFAULT_STEP_S
        offsets = np.arange(count) * step
    offsets, round_s = offsets / speed, (offsets[-1] + step if count else step) / speed
    least_s = count / MAX_RATE_HZ
    slowed = least_s / round_s if round_s < least_s else 1.0
    return offsets * slowed, round_s * slowed, slowed


class Replay:
    """Play ``capture`` into ``feed`` on a thread, at the pace of :func:`schedule`: the
    frames' (or raw event batches') receive times, or one frame per integration time, divided
    by ``speed``, at most :data:`MAX_RATE_HZ`; again and again with ``loop``, each round
    starting when the one before has had its time. :meth:`stop` ends it. The feed's state
    says when the file has been played. ``clock`` and ``sleep`` (seconds to wait; True if
    stopped meanwhile) are the thread's time, for tests."""

    def __init__(self, capture, feed: Feed, *, speed: float = 1.0, loop: bool = False,
                 clock=time.monotonic, sleep=None):
        if not 0 < speed < math.inf:
            raise ValueError(f"speed must be positive and finite, not {speed!r}")
        self.capture, self.feed, self.speed, self.loop = capture, feed, speed, loop
        self.items = list(items_of(capture))
        self._times, self._round_s, self.slowed = schedule(
            self.items, feed.setup.integration_s or 0.0, speed)
        self._stop = threading.Event()
        self._clock, self._sleep = clock, sleep if sleep is not None else self._stop.wait
        self.rounds = 0
        self._thread = threading.Thread(target=self.run, name="fliss-replay", daemon=True)
        start, end = capture.counters.get("board_start", {}), capture.counters.get(
            "board_end", {})
        seconds = capture.attrs.get("capture_s")
        if end and seconds:
            feed.set_file_drops(sum(end.get(name, 0) - start.get(name, 0)
                                    for name in BOARD_DROPS) / seconds)

    def start(self) -> "Replay":
        self._thread.start()
        return self

    def run(self) -> None:
        """Play the file (the thread's work; :meth:`start` runs it on the thread)."""
        feed = self.feed
        if not self.items:
            feed.finish(f"{self.capture.path} holds no frames")
            return
        begun = self._clock()
        while not self._stop.is_set():
            for item, due in zip(self.items, self._times):
                wait = begun + due - self._clock()
                if wait > 0 and self._sleep(wait):
                    return
                if self._stop.is_set():
                    return
                feed.add(item)
            self.rounds += 1
            if not self.loop:
                break
            begun += self._round_s
            if self._clock() > begun + self._round_s:
                begun = self._clock()       # a round behind (a slow machine): no burst to catch up
        feed.finish(f"replayed {len(self.items)} "
                    f"{'frames' if of_capture(self.capture).framed else 'event batches'}"
                    + (f" {self.rounds} times" if self.rounds > 1 else ""))
    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5)

    def wait(self, timeout_s=None) -> bool:
        """Wait for the end of the file; True when it was played."""
        self._thread.join(timeout_s)
        return not self._thread.is_alive()
