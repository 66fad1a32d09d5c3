"""``fliss view FILE --loop`` on a short file: is the replay paced, and what CPU does it take?

A 2-frame file was once looped at 478 784 "frames received" in 7 s at 97 % CPU: each round
started again as soon as the last frame was handed over, without waiting out its frame time.

Two figures per file (2 histogram frames of 8192 bins, integration 1 ms and 10 ms, and the same
frames with their receive times 50 ms apart):

* in process: a :class:`~fliss.host.view.replay.Replay` with ``loop=True`` handing a
  :class:`~fliss.host.view.feed.Feed` (no server) for ``--seconds``: frames handed, frames a
  second, against those due at the file's pace, and the CPU time of the process over that time;
* the command: ``fliss view FILE --loop --for S --view-port 0`` in a child process (the Bokeh
  server running, no browser): its CPU time (user + system) over its wall time.

Run: .venv/bin/python benchmarks/view_loop.py [--seconds 7] [--no-command]
"""

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from fliss.hdl.registers import defaults
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.host.stream import HistogramFrame
from fliss.host.view.feed import Feed, Setup
from fliss.host.view.replay import Replay

CLOCK_HZ = 80_000_000


def two_frames(path, integration_s, gap_s):
    """A histogram capture of two frames, integration ``integration_s``, received ``gap_s``
    apart (0: at the same time)."""
    configuration = defaults(CLOCK_HZ)
    configuration["integration"] = round(integration_s * CLOCK_HZ)
    identity = {"clock_hz": CLOCK_HZ, "protocol": 3, "gateware_version": "0.1"}
    rng = np.random.default_rng(1)
    with CaptureWriter(str(path), mode="histogram", identity=identity,
                       configuration=configuration,
                       attrs={"integration_s": integration_s}) as writer:
        for index in range(2):
            counts = rng.poisson(np.full(8192, 0.05)).astype(np.uint32)
            writer.add_histogram(HistogramFrame(index, 0, counts, True, 0,
                                                1000.0 + index * gap_s))
    return path


def in_process(path, seconds):
    capture = read_capture(path)
    feed = Feed(Setup.of_capture(capture))
    cpu = time.process_time()
    replay = Replay(capture, feed, loop=True).start()
    time.sleep(seconds)
    replay.stop()
    cpu = time.process_time() - cpu
    return feed.status().frames, cpu / seconds


def command(path, seconds):
    fliss = os.path.join(os.path.dirname(sys.executable), "fliss")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()
    subprocess.run([fliss, "view", str(path), "--loop", "--for", f"{seconds}s",
                    "--view-port", "0"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   check=False)
    wall = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu / wall


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=7.0)
    parser.add_argument("--no-command", action="store_true",
                        help="skip the figures of the command (Bokeh's start takes seconds)")
    args = parser.parse_args(argv)
    print(f"{'file':<32} {'frames':>8} {'frames/s':>9} {'due/s':>6} {'CPU (replay)':>13} "
          f"{'CPU (fliss view)':>17}")
    with tempfile.TemporaryDirectory() as folder:
        for integration_s, gap_s in ((1e-3, 0.0), (10e-3, 0.0), (1e-3, 50e-3)):
            path = two_frames(os.path.join(folder, "two.h5"), integration_s, gap_s)
            due = 1 / gap_s if gap_s else 1 / integration_s
            frames, cpu = in_process(path, args.seconds)
            whole = "" if args.no_command else f"{command(path, args.seconds):>16.0%}"
            name = f"2 frames, {integration_s * 1e3:g} ms" + \
                (f", received {gap_s * 1e3:g} ms apart" if gap_s else "")
            print(f"{name:<32} {frames:>8} {frames / args.seconds:>9.0f} {due:>6.0f} "
                  f"{cpu:>13.0%} {whole:>17}")


if __name__ == "__main__":
    main()
