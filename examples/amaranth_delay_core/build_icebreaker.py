"""Build the range finder for the iCEBreaker and check its timing.

Usage, from this folder, with FLISS's boards extra installed (``pip install 'fliss[boards]'``:
amaranth-boards and the YoWASP tools)::

    python build_icebreaker.py [--clock 48e6] [--build-dir build]

It prints the Fmax and the utilisation and exits with status 1 if timing fails at the clock.
The build goes through ``fliss.boards.build.build_board``, which puts the design under
``fliss.boards.BoardTop`` (the PLL to the clock, the reset, the pins by name).
"""

import argparse
import sys
from pathlib import Path

from ranger_board import RangerOnBoard


#: The clock the range finder is built at, in Hz (the iCE40 PLL makes exactly 48 MHz from 12).
CLOCK_HZ = 48_000_000


def build(clock_hz=CLOCK_HZ, build_dir="build"):
    """Build the bitstream; a ``fliss.boards.build.BuildResult`` (Fmax, utilisation). Raises
    ``ImportError`` without the boards extra, ``ToolchainError`` if the build fails."""
    from fliss.boards.build import build_board
    return build_board("icebreaker", clock_hz=clock_hz, build_dir=Path(build_dir),
                       design=RangerOnBoard)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clock", type=float, default=CLOCK_HZ, help="clock in Hz")
    parser.add_argument("--build-dir", default="build", help="build folder")
    args = parser.parse_args(argv)
    try:
        from fliss.boards.build import ToolchainError
        result = build(args.clock, args.build_dir)
    except ImportError as error:
        print(f"error: {error} (install the boards extra: pip install 'fliss[boards]')",
              file=sys.stderr)
        return 2
    except (ToolchainError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(result.summary())
    if not result.timing_met:
        print(f"error: timing failed at {result.clock_hz / 1e6:.3f} MHz", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
