"""``fliss selftest``: the board's self-test on a loopback (:mod:`fliss.host.selftest`): one
table, a line per check, and the verdict: exit status 0 when every check passed, 1 when one
failed, :data:`INCOMPLETE` when none failed but some were skipped (not a full self-test), 130
when interrupted (the checks finished are printed)."""

import sys

from ..selftest import CHECKS, JUMPERS, SelfTestInterrupted, selftest
from .common import Progress, sigterm_interrupts
from .port_options import add_port_arguments, connect


__all__ = ["INCOMPLETE", "register", "run"]


#: Exit status of a self-test with skipped checks and no failure.
INCOMPLETE = 3


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
                    "pass, fail, or skipped with the reason, and the verdict: exit status 0 "
                    "only when every check passed, 1 when one failed, 3 when some were skipped "
                    "(not a full self-test). On a board slower than real time (the virtual "
                    "board's simulation) it measures the board's pace first and shortens its "
                    "acquisitions and lengthens its waits to match. The delays are checked through "
                    "the aggressor only (the victim's own hits cannot show them). The trigger "
                    "outputs pulse during the test: disconnect laser drivers. The settings it "
                    "changes are put back, after Ctrl-C or kill too.")
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
    with connect(args) as board, sigterm_interrupts():     # kill: as Ctrl-C, settings put back
        progress = Progress(len(CHECKS), "checks", enabled=not quiet, interval_s=1.0)
        try:
            result = selftest(board, jumper=args.jumper, reference=delays, progress=progress)
        except SelfTestInterrupted as interrupted:
            progress.close()
            progress.enabled = False
            if interrupted.result.checks:
                print(interrupted.result.table())
            print(f"fliss selftest: interrupted: {interrupted.result.summary()}",
                  file=sys.stderr)
            return 130
        finally:
            progress.close()
    print(result.table())
    verdict = result.verdict
    if verdict == "fail":
        print(f"fliss selftest: {result.summary()}", file=sys.stderr)
        return 1
    pace = "" if result.pace is None or result.pace >= 0.5 else \
        f", a board at {result.pace:.2g} of real time"
    if verdict == "incomplete":
        print(f"fliss selftest: incomplete: {result.summary()} (loopback: {result.loop}"
              f"{pace})", file=sys.stderr)
        return INCOMPLETE
    if not quiet:
        print(f"fliss selftest: {result.summary()} in {result.elapsed_s:.1f} s (loopback: "
              f"{result.loop}{pace})", file=sys.stderr)
    return 0
