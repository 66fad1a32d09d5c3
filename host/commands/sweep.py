"""``fliss sweep``: a grid of simulation points (a TOML spec) on Dask, into a directory.

The spec is read by :mod:`~fliss.host.sweep.spec`, run by :mod:`~fliss.host.sweep.engine` and
drawn by :mod:`~fliss.host.sweep.figures`; this module is the command line: the progress bar,
Ctrl-C and SIGTERM, and the report. The format is in ``docs/sweeps.md``.
"""

import argparse
import os
import sys

from .common import progress_bar, sigterm_interrupts
from ..errors import UserError
from ..sweep.engine import STORE_NAME, SweepError, cluster, run_sweep, table_rows, Store
from ..sweep.spec import SpecError, load


__all__ = ["register", "run"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "sweep", formatter_class=formatter,
        help="run a parameter sweep (TOML spec) on Dask into a directory",
        description="Runs every point of the grid in SPEC (docs/sweeps.md) on a Dask cluster: "
                    "a LocalCluster on this machine, or an existing scheduler. Each finished "
                    "point is stored in DIR/points as it finishes, and a run into the same "
                    "directory computes only the points not stored yet, so Ctrl-C (or kill) "
                    "keeps what is finished. Writes DIR/results.parquet (one row per point: "
                    "parameters, then metrics) and PNG figures.")
    parser.add_argument("spec", metavar="SPEC", help="sweep specification (TOML)")
    parser.add_argument("-o", "--out", required=True, metavar="DIR", default=argparse.SUPPRESS,
                        help="output directory (created; reused to resume)")
    parser.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1), metavar="N",
                        help="workers of the LocalCluster, one point at a time each")
    parser.add_argument("--threads", action="store_true",
                        help="workers are threads of this process instead of processes")
    parser.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                        help="use an existing Dask scheduler instead of a LocalCluster "
                             "(its workers must have fliss installed)")
    parser.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    parser.set_defaults(run=run)


def run(args):
    if args.workers < 1:
        raise UserError(f"--workers must be at least 1, not {args.workers}")
    try:
        spec = load(args.spec)
    except SpecError as error:
        raise UserError(str(error)) from None
    if os.path.exists(args.out) and not os.path.isdir(args.out):
        raise UserError(f"{args.out} exists and is not a directory")
    try:
        os.makedirs(args.out, exist_ok=True)
    except OSError as error:
        raise UserError(f"cannot create {args.out}: {error.strerror or error}") from None
    quiet = getattr(args, "quiet", 0) > 0
    kind = ("thread", "threads") if args.threads else ("process", "processes")
    where = args.scheduler or f"{args.workers} worker {kind[args.workers > 1]}"
    if not quiet:
        print(f"fliss sweep: {len(spec.points())} points of {args.spec} on {where}, into "
              f"{args.out}", file=sys.stderr)
    update, close = progress_bar(enabled=not quiet)
    try:
        with sigterm_interrupts(), cluster(args.workers, processes=not args.threads,
                                           scheduler=args.scheduler) as client:
            outcome = run_sweep(spec, args.out, client, progress=update)
    except SweepError as error:
        raise UserError(str(error)) from None
    finally:
        close()
    if not quiet:
        print(f"{outcome.computed} points computed in {outcome.elapsed_s:.1f} s, "
              f"{outcome.reused} found finished in {os.path.join(args.out, STORE_NAME)}",
              file=sys.stderr)
    if outcome.table and not args.no_figures and not outcome.interrupted:
        from ..sweep.figures import figures
        written, notes = figures(table_rows(spec, Store(args.out)), args.out,
                                 spec.varied())
        if not quiet:
            for note in notes:
                print(f"fliss sweep: {note}", file=sys.stderr)
            for name in written:
                print(f"figure: {os.path.join(args.out, name)}")
    if outcome.interrupted:
        print(f"fliss: interrupted; {outcome.total - outcome.missing} of {outcome.total} points "
              f"finished and kept in {args.out}; run the same command again to compute the "
              f"other {outcome.missing}", file=sys.stderr)
        return 130
    if not quiet and outcome.table:
        print(f"results: {outcome.table}")
    return 0
