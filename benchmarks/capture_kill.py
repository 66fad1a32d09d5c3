"""What a ``kill -9`` of ``fliss capture`` costs (docs/file-format.md says why).

A real ``fliss capture`` process captures 2 ms histograms from the Python model board and is
killed with SIGKILL at a range of moments. For each kill it prints the histograms the board had
sent (its own record), the rows the file gives back (``read_capture``), the rows lost, and the
unreadable window: the seconds from the receive time of the last row in the file to the kill,
beside its bound, the writer's flush interval (:data:`fliss.host.fileformat.FLUSH_S`) plus the
time between two rows. (The model board makes histograms slower than real time, so the rows
lost say less than the window.) A row that differs from what the board sent counts as wrong.

Usage: python benchmarks/capture_kill.py [--kills 8] [--integration 2ms] [--bin-shift 0]
"""

import argparse
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from fliss.host.client import BoardClient
from fliss.host.fileformat import FLUSH_S, read_capture
from fliss.host.units import parse_time
from fliss.sim.boards.model import model_board


def one_kill(folder, index, after_s, integration, shift):
    output = Path(folder) / f"kill-{index}.h5"
    bins = 8192 >> shift
    with model_board() as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": shift})
        first = model.next_frame
        process = subprocess.Popen(
            [sys.executable, "-m", "fliss", "-q", "capture", "--port", model.path,
             "--timeout", "2", "--integration", integration, "--acquisitions", "1000000",
             "-o", str(output)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        while model.next_frame <= first:          # the capture has started
            time.sleep(0.01)
        time.sleep(after_s)
        process.send_signal(signal.SIGKILL)
        killed = time.time()
        process.wait()
        sent = model.sent_histograms(bins, whole=True)
    capture = read_capture(output)
    wrong = sum(not np.array_equal(row, sent.get(int(frame), -1))
                for row, frame in zip(capture.histograms, capture.frames))
    started = int(capture.frames[0]) if len(capture.frames) else min(sent)
    sent_count = sum(1 for frame in sent if frame >= started)
    window_s = killed - float(capture.times_s[-1]) if len(capture.times_s) else float("nan")
    return sent_count, len(capture.histograms), wrong, window_s


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kills", type=int, default=8)
    parser.add_argument("--integration", default="2ms")
    parser.add_argument("--bin-shift", type=int, default=0)
    args = parser.parse_args()
    parse_time(args.integration)
    print(f"SIGKILL of fliss capture, {args.integration} histograms of {8192 >> args.bin_shift} "
          f"bins; the writer flushes every {FLUSH_S:g} s")
    print(f"{'kill at (s)':>11} {'sent':>6} {'in file':>8} {'lost':>5} {'window (s)':>11} "
          f"{'bound (s)':>10} {'wrong':>6}")
    worst = 0.0
    with tempfile.TemporaryDirectory() as folder:
        for index in range(args.kills):
            after_s = 1.0 + 0.37 * index
            sent, kept, wrong, window_s = one_kill(folder, index, after_s, args.integration,
                                                   args.bin_shift)
            bound_s = FLUSH_S + after_s / max(sent, 1)     # flush interval + one row
            worst = max(worst, window_s)
            print(f"{after_s:>11.2f} {sent:>6} {kept:>8} {sent - kept:>5} {window_s:>11.3f} "
                  f"{bound_s:>10.3f} {wrong:>6}")
    print(f"worst unreadable window: {worst:.3f} s (flush interval {FLUSH_S:g} s)")


if __name__ == "__main__":
    main()
