"""``fliss reproduce``: the experiments of section 6 of the paper, on the scene simulator.

:func:`fliss.host.reproduce.run.reproduce` runs them and writes the report and the figures; this
module is the command line.
"""

import argparse
import math
import os
import re
import sys

from ..errors import UserError
from ..paths import check_output_dir
from ..reproduce.experiments import Config, ReproductionError
from ..reproduce.report import s_text
from ..reproduce.run import reproduce
from .common import sigterm_interrupts
from ..sweep.engine import SweepError
from ..units import parse_frequency, parse_time


__all__ = ["register", "run"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "reproduce", formatter_class=formatter,
        help="reproduce the paper's experiments (Figures 7-12) on the scene simulator",
        description="Runs the experiments of section 6 of the paper with the paper's "
                    "parameters on the photon-level scene simulator and writes PNG figures in "
                    "the spirit of Figures 7 to 12 and a results table (CSV and Markdown) next "
                    "to the paper's reported values. Photon rates, background, dead time and "
                    "jitter are not given in the paper; see docs/results.md.")
    parser.add_argument("--quick", action="store_true",
                        help="20 acquisitions per setting instead of 300 (under a minute)")
    parser.add_argument("--out", default="fliss-results", metavar="DIR",
                        help="output directory")
    parser.add_argument("--acquisitions", type=int, default=argparse.SUPPRESS, metavar="N",
                        help="acquisitions per setting: 300, or 20 with --quick")
    parser.add_argument("--t-int", nargs="+", default=["10ms", "30ms", "100ms"], metavar="T",
                        help="integration times; the longest is used for Figures 7, 8, 10, 12")
    parser.add_argument("--lengths", type=int, nargs="*", default=[3, 4, 5, 6], metavar="L",
                        help="LFSR lengths of the complete m-sequences (Figure 9)")
    parser.add_argument("--mask-widths", type=int, nargs="*", default=[1, 2, 3, 4, 5, 6],
                        metavar="W", help="mask widths on the 32-bit LFSR (Figure 12)")
    parser.add_argument("--signal", type=float, default=0.05, metavar="MEAN",
                        help="victim echo: mean detections per pulse")
    parser.add_argument("--aggressor", type=float, default=0.05, metavar="MEAN",
                        help="aggressor: mean detections per pulse at the victim's pixel")
    parser.add_argument("--background", default="100kHz", metavar="RATE",
                        help="ambient light plus dark counts")
    parser.add_argument("--dead-time", default="20ns", metavar="T", help="SPAD dead time")
    parser.add_argument("--jitter", default="100ps", metavar="T",
                        help="SPAD and TDC timing jitter, FWHM")
    parser.add_argument("--keep", choices=["first", "last"], default="last",
                        help="photon the single-hit TDC keeps per laser cycle")
    parser.add_argument("--aggressor-prf", choices=["effective", "nominal"], default="effective",
                        help="the aggressor's PRF: the victim's effective PRF (as in the paper) "
                             "or its nominal PRF")
    parser.add_argument("--seed", type=int, default=2019, help="seed of the photon statistics")
    parser.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), metavar="N",
                        help="worker processes of the local Dask cluster")
    parser.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                        help="run on an existing Dask scheduler instead (as fliss sweep does)")
    parser.add_argument("--no-figures", action="store_true", help="skip the PNG figures")
    parser.set_defaults(run=run)


def _parse(function, text, option):
    """A positive quantity with units, or zero ("0", "0ns", "0 Hz")."""
    if re.fullmatch(r"\s*[-+]?0*\.?0*\s*[a-zµ]*\s*", str(text), flags=re.IGNORECASE) and \
            re.search(r"0", str(text)):
        return 0.0
    try:
        return float(function(text))
    except ValueError as error:
        raise UserError(f"{option}: {error}") from None


def run(args):
    acquisitions = getattr(args, "acquisitions", None)
    if acquisitions is None:
        acquisitions = 20 if args.quick else 300
    if args.jobs < 1:
        raise UserError(f"--jobs must be at least 1, not {args.jobs}")
    config = Config(
        acquisitions=acquisitions,
        t_int_s=tuple(sorted({_parse(parse_time, text, "--t-int") for text in args.t_int})),
        lengths=tuple(args.lengths), mask_widths=tuple(args.mask_widths),
        signal=args.signal, aggressor=args.aggressor,
        background_hz=_parse(parse_frequency, args.background, "--background"),
        dead_time_s=_parse(parse_time, args.dead_time, "--dead-time"),
        jitter_fwhm_s=_parse(parse_time, args.jitter, "--jitter"),
        keep=args.keep, aggressor_prf=args.aggressor_prf, seed=args.seed)
    try:
        config.check()
    except ValueError as error:
        raise UserError(str(error)) from None
    check_output_dir(args.out, flag="--out")        # before hours of work
    if not args.quiet:
        where = args.scheduler or f"{args.jobs} worker(s)"
        print(f"fliss reproduce: {config.acquisitions} acquisitions per setting, "
              f"on {where}, writing to {args.out}", file=sys.stderr)
    try:
        with sigterm_interrupts():
            rows = reproduce(config, args.out, workers=args.jobs, figures=not args.no_figures,
                             stream=None if args.quiet else sys.stderr,
                             scheduler=args.scheduler)
    except (ReproductionError, SweepError) as error:
        raise UserError(str(error)) from None
    if not args.quiet:
        for row in rows:
            if math.isfinite(row["s_db"]):
                print(f"{row['setting']:>10}  T_int {row['t_int_ms']:>5g} ms  "
                      f"S = {s_text(row)} dB")
        print(f"results: {os.path.join(args.out, 'results.md')}")
    return 0
