"""Fmax and utilisation of the board designs, over several placement seeds.

Builds each design with the YoWASP tools (``pip install -e '.[boards]'``), as
``python -m fliss.boards.build`` does, and prints per design and seed the Fmax of the design
clock, whether timing is met at the real clock, the LUT/FF count and the build time; then the
range over the seeds next to the goal. The baseline, built in the same run, is the delay core
alone (``core_probe.DelayCoreProbe``, its settings shifted in from a pin) on the same board and
clock: the pulse path without the link side, the histogram and the TDC interfaces.

Goals: ULX3S 80 MHz with an Fmax of at least 100 MHz; iCEBreaker 79.5 MHz (today it carries the
smaller FlissTop build at 36 MHz, see docs/boards.md).

With ``--at-goal`` each design is built for a clock at its goal instead (the PLL set for it, and
nextpnr told to meet it): a build constrained at the real clock stops improving a path once it
meets it, so this is the fair test of the goal.

Usage: python benchmarks/board_fmax.py [--board ulx3s|icebreaker] [--seeds N] [--at-goal]
"""

import argparse
import tempfile
from pathlib import Path

from fliss.boards.build import BOARD_CLOCK_HZ, BOARD_DESIGN, build_board

from core_probe import DelayCoreProbe


GOAL_MHZ = {"ulx3s": 100.0, "icebreaker": 79.5}
BASELINE = "core_probe:DelayCoreProbe"


def measure(board, design, seeds, build_root, clock_hz=None):
    results = []
    for seed in range(seeds):
        factory = DelayCoreProbe if design == BASELINE else design
        result = build_board(board, design=factory, seed=seed + 1, clock_hz=clock_hz,
                             build_dir=Path(build_root, f"{board}-{design.split(':')[1]}-{seed}"))
        fmax = result.fmax_mhz.get(result.design_clock, 0.0)
        lut, ff = result.utilisation["LUT"][0], result.utilisation["FF"][0]
        print(f"  {design:28} seed {seed + 1}: Fmax {fmax:7.2f} MHz  "
              f"{'met' if result.timing_met else 'FAILS'} at {result.clock_hz / 1e6:.2f} MHz  "
              f"LUT {lut:5}  FF {ff:5}  {result.build_time_s:4.0f} s", flush=True)
        results.append(fmax)
    return results


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--board", choices=sorted(BOARD_DESIGN), action="append",
                        help="board (repeat for several; default: both)")
    parser.add_argument("--seeds", type=int, default=3, help="placement seeds per design")
    parser.add_argument("--at-goal", action="store_true",
                        help="build for a clock at the Fmax goal instead of the board's clock")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1, not {args.seeds}")

    with tempfile.TemporaryDirectory(prefix="fliss-fmax-") as build_root:
        for board in args.board or sorted(BOARD_DESIGN):
            clock_hz = GOAL_MHZ[board] * 1e6 if args.at_goal else BOARD_CLOCK_HZ[board]
            print(f"{board} built for {clock_hz / 1e6:g} MHz "
                  f"(goal: Fmax {GOAL_MHZ[board]} MHz)")
            designs = [BOARD_DESIGN[board]] + \
                ([BASELINE] if BOARD_DESIGN[board] != BASELINE else [])
            for design in designs:
                fmax = measure(board, design, args.seeds, build_root, clock_hz)
                label = "baseline" if design == BASELINE and len(designs) > 1 else "design"
                print(f"  {label} {design}: Fmax {min(fmax):.2f}–{max(fmax):.2f} MHz over "
                      f"{len(fmax)} seeds; goal {GOAL_MHZ[board]} MHz "
                      f"{'met' if min(fmax) >= GOAL_MHZ[board] else 'NOT met'}")


if __name__ == "__main__":
    main()
