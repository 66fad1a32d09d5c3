"""``fliss calibrate``: the fine TDC's code-density calibration (:mod:`fliss.host.calibration`),
its table stored on the board, with progress while it runs."""

import sys

from ..calibration import LEAST_HITS_PER_CODE, TABLE_ENTRIES, calibrate
from ..errors import UserError
from ..pace import REAL_TIME, host_s, measure_pace
from ..settings import duration_s
from .common import Progress, sigterm_interrupts
from .port_options import add_port_arguments, connect


__all__ = ["SIMULATION_DURATION_S", "SIMULATION_FRAME_S", "register", "run"]


#: The oscillator's time on a board slower than real time (a simulation), in histograms of
#: :data:`SIMULATION_FRAME_S`, unless ``--duration`` is given: some 29 000 hits, 45 a code, above
#: the table's least.
SIMULATION_DURATION_S = 0.012
SIMULATION_FRAME_S = 0.002


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
                    f"back. A table needs {LEAST_HITS_PER_CODE} hits a code on average (each "
                    "code's width then within 20 %): with fewer the board's table is left as "
                    "it was, unless --force. Ctrl-C while the table is written leaves it "
                    "partial, which it says.")
    add_port_arguments(parser)
    parser.add_argument("--duration", default="auto", metavar="TIME",
                        help="how long to histogram the oscillator's codes, in the board's "
                             "time; auto: 1s, or on a board slower than real time (the virtual "
                             f"board's simulation) {SIMULATION_DURATION_S * 1e3:g}ms")
    parser.add_argument("--force", action="store_true",
                        help="write the table even from fewer hits than it needs")
    parser.set_defaults(run=run)


def run(args):
    seconds = None
    if args.duration != "auto":
        seconds = duration_s(args.duration, f"--duration {args.duration}")
        if not seconds > 0:
            raise UserError(f"--duration must be positive, not {args.duration}")
    quiet = getattr(args, "quiet", 0) > 0
    with connect(args) as board, sigterm_interrupts():     # kill: as Ctrl-C, which it says
        pace = measure_pace(board)
        slow = pace < REAL_TIME
        frame_s = SIMULATION_FRAME_S if slow else 0.1
        if seconds is None:
            seconds = SIMULATION_DURATION_S if slow else 1.0
        frame_s = min(frame_s, seconds)
        frames = max(1, round(seconds / frame_s))
        if slow and not quiet:
            print(f"fliss calibrate: the board runs at {pace:.2g} of real time (a "
                  f"simulation): {seconds:g} s of its oscillator take some "
                  f"{host_s(seconds, pace):.0f} s, the table's {3 * TABLE_ENTRIES} commands "
                  f"more", file=sys.stderr)
        bars = []

        def progress(stage):
            if bars:
                bars[-1].close()
            total, unit = (frames, "histograms") if stage == "histograms" else \
                (2 * TABLE_ENTRIES, "table entries written and read back")
            bars.append(_Stage(Progress(total, unit, enabled=not quiet, interval_s=5.0)))
            return bars[-1]

        timeout_s = None
        if slow:
            timeout_s = max(2.0, board.client.timeout_s) + host_s(2 * frame_s + 0.05, pace)
        try:
            result = calibrate(board, seconds, integration_s=frame_s, timeout_s=timeout_s,
                               force=args.force, progress=progress)
        except KeyboardInterrupt:       # (before the table: an interrupted write says so)
            print("fliss calibrate: interrupted before the table was written: the board's "
                  "table is left as it was", file=sys.stderr)
            return 130
        finally:
            for bar in bars:
                bar.close()
    if not quiet:
        forced = "" if result.counts.sum() >= LEAST_HITS_PER_CODE * (
            result.last_code - result.first_code + 1) else " (forced: too few hits)"
        print(f"fliss calibrate: {int(result.counts.sum())} hits on codes {result.first_code}-"
              f"{result.last_code} (mean {result.mean_code_s * 1e12:.1f} ps, DNL "
              f"{result.dnl_max:.2f}, INL {result.inl_max:.2f} codes); table written to the "
              f"board and read back{forced}", file=sys.stderr)
    return 0


class _Stage:
    """The progress of the table's writing and reading back on one bar: the entries read
    back count after those written."""

    def __init__(self, bar):
        self.bar, self.reading = bar, False

    def update(self, done, extra=""):
        if extra == "entries read back":
            self.reading = True
        self.bar.update(done + (TABLE_ENTRIES if self.reading else 0), extra)

    def close(self):
        self.bar.close()
