"""``fliss selftest``: the board's self-test on a loopback (:mod:`fliss.host.selftest`): one
table, a line per check, and a non-zero exit status if one fails."""

import sys

from ..selftest import CHECKS, JUMPERS, selftest
from .common import Progress
from .port_options import add_port_arguments, connect


__all__ = ["register", "run"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "selftest", formatter_class=formatter,
        help="check the board on a loopback: TDC, delays, histograms, calibration, link",
        description="Runs the self-test (docs/bring-up.md) in some seconds. With no --jumper, "
                    "on the fine TDC's internal loopback (the laser's and the aggressor's "
                    "outputs read back at their pads: every check, no wire); a build without "
                    "it (no fine TDC) checks only the link then. Or on a jumper wire from the "
                    "victim's laser output (--jumper laser) or the aggressor's trigger "
                    "(--jumper aggressor) to the photon input. Prints one line per check: "
                    "pass, fail, or skipped with the reason. The delays are checked through "
                    "the aggressor only (the victim's own hits cannot show them). The trigger "
                    "outputs pulse during the test: disconnect laser drivers. The settings it "
                    "changes are put back.")
    add_port_arguments(parser)
    parser.add_argument("--jumper", choices=JUMPERS, default=None,
                        help="what a jumper wire carries to the photon input (none: the "
                             "internal loopback, or the checks that need hits are skipped on a "
                             "build without it)")
    parser.set_defaults(run=run)


def run(args):
    # The reference model of the delays, for the delays check (the library takes it as a
    # parameter: the code that talks to a real board does not import the simulator).
    from ...sim.models.delay import delays

    quiet = getattr(args, "quiet", 0) > 0
    with connect(args) as board:
        progress = Progress(len(CHECKS), "checks", enabled=not quiet, interval_s=1.0)
        try:
            result = selftest(board, jumper=args.jumper, reference=delays, progress=progress)
        finally:
            progress.close()
    print(result.table())
    failed = [check.name for check in result.checks if check.outcome == "fail"]
    if failed:
        print(f"fliss selftest: failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    if not quiet:
        print(f"fliss selftest: passed in {result.elapsed_s:.1f} s (loopback: {result.loop})",
              file=sys.stderr)
    return 0
