"""Time ``fliss selftest`` (no jumper: the internal loopback) on the virtual board with the fine
TDC, check by check: wall time, clock cycles simulated and bytes each way, from the board's
statistics file (docs/virtual-board.md). The durations are the virtual self-test's
(``tests/boards/test_virtual_selftest.py``) unless ``--durations`` gives others (JSON)."""

import argparse
import json
import time

from fliss.host.board import connect
from fliss.host.selftest import selftest
from fliss.host.virtual import VirtualBoard
from fliss.sim.models.delay import delays


#: The virtual self-test's durations (tests/boards/test_virtual_selftest.py).
DURATIONS_S = {"raw": 0.3, "histogram": 0.0005, "calibration": 0.012, "calibration_frame": 0.002}


class _Marks:
    # The board's statistics after each check (the self-test's progress)
    def __init__(self, board):
        self.board, self.marks = board, []

    def update(self, done, name):
        self.marks.append((name, time.monotonic(), self.board.stats()))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--durations", type=json.loads, default=DURATIONS_S,
                        help="the self-test's durations_s, as JSON")
    parser.add_argument("--seed", type=int, default=3, help="the virtual board's seed")
    args = parser.parse_args(argv)
    started = time.monotonic()
    board = VirtualBoard("verilator", engine="cocotb", fine_tdc=True, seed=args.seed)
    board.start(timeout_s=3600)
    print(f"start-up {time.monotonic() - started:.1f} s")
    marks = _Marks(board)
    try:
        with connect(board.path, timeout_s=10.0) as client:
            marks.update(0, "begin")
            result = selftest(client, reference=delays, durations_s=args.durations,
                              progress=marks)
            marks.update(0, "end")
    finally:
        board.stop()
    print(result.table())
    print(f"{'check':12s} {'wall':>7s} {'cycles':>10s} {'to host':>8s} {'to board':>8s}")
    for (_, t0, s0), (name, t1, s1) in zip(marks.marks, marks.marks[1:]):
        print(f"{name:12s} {t1 - t0:6.1f}s {s1['cycles'] - s0['cycles']:10d} "
              f"{s1['bytes_to_host'] - s0['bytes_to_host']:8d} "
              f"{s1['bytes_to_board'] - s0['bytes_to_board']:8d}")
    first, last = marks.marks[0][2], marks.marks[-1][2]
    print(f"{'all':12s} {result.elapsed_s:6.1f}s {last['cycles'] - first['cycles']:10d} "
          f"{last['bytes_to_host'] - first['bytes_to_host']:8d} "
          f"{last['bytes_to_board'] - first['bytes_to_board']:8d}")


if __name__ == "__main__":
    main()
