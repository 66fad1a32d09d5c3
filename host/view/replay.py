"""A capture file played back into a :class:`~fliss.host.view.feed.Feed` (``fliss view
FILE``): its frames (or raw event batches) at the pace they were captured, times ``speed``, on
a thread of their own."""

import threading
import time

import numpy as np

from ..stream import DepthFrame, EventBatch, HistogramFrame
from .feed import BOARD_DROPS, Feed


__all__ = ["items_of", "Replay"]


def items_of(capture):
    """The items a board sent for ``capture`` (a :class:`~fliss.host.fileformat.Capture`),
    as the stream assembler makes them: histogram frames, depth frames, or the raw events cut
    into as many batches as the file records."""
    mode = capture.mode
    if mode == "raw":
        batches = max(len(capture.batch_times_s), 1)
        times = capture.batch_times_s if len(capture.batch_times_s) else [0.0]
        for events, time_s in zip(np.array_split(capture.events, batches), times):
            yield EventBatch(events, float(time_s))
        return
    pixels = capture.pixels
    first = int(pixels[0]) if len(pixels) else 0
    pixel_bits = int(len(pixels)).bit_length() - 1 if len(pixels) else 0
    for index in range(len(capture.frames)):
        frame, complete = int(capture.frames[index]), bool(capture.complete[index])
        shift = int(capture.shifts[index]) if len(capture.shifts) else capture.shift
        time_s = float(capture.times_s[index]) if len(capture.times_s) else 0.0
        if mode == "depth":
            depth = capture.depth
            detected = np.asarray(depth["detected"][index], dtype=bool)
            yield DepthFrame(frame, first, shift, np.asarray(depth["position"][index]),
                             np.asarray(depth["height"][index]),
                             np.asarray(depth["background"][index]), detected, time_s,
                             pixel_bits)
        else:
            counts = np.asarray(capture.histograms[index])
            yield HistogramFrame(frame, shift, counts.reshape(-1), complete, 0, time_s,
                                 pixel_bits if counts.ndim > 1 else 0, first)


class Replay:
    """Play ``capture`` into ``feed`` on a thread: one frame per integration time divided by
    ``speed`` (raw events: at the times their batches arrived), again and again with
    ``loop``; :meth:`stop` ends it. The feed's state says when the file has been played."""

    def __init__(self, capture, feed: Feed, *, speed: float = 1.0, loop: bool = False):
        if not speed > 0:
            raise ValueError(f"speed must be positive, not {speed!r}")
        self.capture, self.feed, self.speed, self.loop = capture, feed, speed, loop
        self.items = list(items_of(capture))
        self._times = self._schedule()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="fliss-replay", daemon=True)
        start, end = capture.counters.get("board_start", {}), capture.counters.get(
            "board_end", {})
        seconds = capture.attrs.get("capture_s")
        if end and seconds:
            feed.set_file_drops(sum(end.get(name, 0) - start.get(name, 0)
                                    for name in BOARD_DROPS) / seconds)

    def _schedule(self):
        # Seconds from the start at which each item is due.
        if self.capture.mode == "raw" and len(self.items) > 1:
            times = np.array([item.time_s for item in self.items])
            return (times - times[0]) / self.speed
        step = self.feed.setup.integration_s or 0.1
        return np.arange(len(self.items)) * step / self.speed

    def start(self) -> "Replay":
        self._thread.start()
        return self

    def _run(self):
        feed = self.feed
        if not self.items:
            feed.finish(f"{self.capture.path} holds no frames")
            return
        rounds = 0
        while not self._stop.is_set():
            started = time.monotonic()
            for item, due in zip(self.items, self._times):
                wait = due - (time.monotonic() - started)
                # (items due within a few milliseconds go at once: no sleep per item at 1 kHz)
                if wait > 0.005 and self._stop.wait(wait):
                    return
                if self._stop.is_set():
                    return
                feed.add(item)
            rounds += 1
            if not self.loop:
                break
        feed.finish(f"replayed {len(self.items)} "
                    f"{'event batches' if self.capture.mode == 'raw' else 'frames'}"
                    + (f" {rounds} times" if rounds > 1 else ""))

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5)

    def wait(self, timeout_s=None) -> bool:
        """Wait for the end of the file; True when it was played."""
        self._thread.join(timeout_s)
        return not self._thread.is_alive()
