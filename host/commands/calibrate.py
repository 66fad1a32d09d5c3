"""``fliss calibrate``: the fine TDC's code-density calibration (:mod:`fliss.host.calibration`),
its table stored on the board."""

import sys

from ..calibration import calibrate
from ..errors import UserError
from ..settings import duration_s
from .port_options import add_port_arguments, connect


__all__ = ["register", "run"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "calibrate", formatter_class=formatter,
        help="calibrate the fine TDC (code density) and store its table on the board",
        description="Histograms the fine TDC's raw tap codes with the on-chip oscillator as "
                    "its input (hits uncorrelated with the clock), computes each code's time "
                    "(fliss.analysis.calibration), writes the table to the board, reads it "
                    "back and compares. Captures with the fine TDC record the table the board "
                    "holds. The table is lost when the FPGA is configured again: calibrate "
                    "after each power-up (docs/finetdc.md). The settings it changes are put "
                    "back.")
    add_port_arguments(parser)
    parser.add_argument("--duration", default="1s", metavar="TIME",
                        help="how long to histogram the oscillator's codes")
    parser.set_defaults(run=run)


def run(args):
    seconds = duration_s(args.duration, f"--duration {args.duration}")
    if not seconds > 0:
        raise UserError(f"--duration must be positive, not {args.duration}")
    with connect(args) as board:
        result = calibrate(board, seconds)
    if getattr(args, "quiet", 0) <= 0:
        print(f"fliss calibrate: {int(result.counts.sum())} hits on codes {result.first_code}-"
              f"{result.last_code} (mean {result.mean_code_s * 1e12:.1f} ps, DNL "
              f"{result.dnl_max:.2f}, INL {result.inl_max:.2f} codes); table written to the "
              f"board and read back", file=sys.stderr)
    return 0
