"""``fliss sequence``: the delays (or laser fire times) of a delay source, one a line."""

import argparse
import sys

import numpy as np

from ...hdl.delay.modes import MODES
from ...sim.models import delay as delay_model
from ...sim.models import scheduler as scheduler_model
from ...hdl.delay.settings import parse_hex
from ..errors import UserError
from .common import add_timing_options, timing_from_args


__all__ = ["register", "run_sequence"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "sequence", formatter_class=formatter,
        help="print the delays (or laser fire times) of a delay source",
        description="One delay in clock cycles per line, exactly as the gateware produces them "
                    "after a start; with --times, the cycle of each laser rising edge counted "
                    "from the first frame.")
    parser.add_argument("--mode", default="mseq", choices=[row.name for row in MODES.values()],
                        help="delay source")
    parser.add_argument("--length", type=int, default=6, metavar="L",
                        help="register length of the mseq source, 2 to 32")
    parser.add_argument("--mask-width", type=int, default=6, metavar="W",
                        help="mask width of the masked or keyed source, 1 to 16")
    parser.add_argument("--key", metavar="HEX",
                        help="key of the keyed source (20 hex digits, as the test vectors print "
                             "it)")
    parser.add_argument("--iv", metavar="HEX",
                        help="IV of the keyed source: the IV in use, as the board reads it")
    parser.add_argument("--seed", type=_seed, default=1, metavar="S",
                        help="non-zero register seed (decimal or 0x hex)")
    parser.add_argument("--count", type=int, default=16, metavar="N",
                        help="number of pulses (at most 16777216)")
    parser.add_argument("--times", action="store_true",
                        help="print laser fire times in clock cycles instead of delays")
    parser.add_argument("--grid", action="store_true",
                        help="grid scheduler mode (pulse k at k*T + delay) for --times")
    parser.add_argument("--pulse-width", type=int, default=1, metavar="CYCLES",
                        help="laser pulse width in clock cycles, checked against the period")
    add_timing_options(parser)
    parser.set_defaults(run=run_sequence)


def _seed(text):
    try:
        return int(text, 0)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number (decimal or 0x hex)") from None


#: The most pulses printed (their delays are made in memory at once: 16 Mi, 128 MB).
MAX_COUNT = 1 << 24


#: The option of each setting a delay mode may read (the mode table's ``needs``).
_SETTING_OPTIONS = {"length": "--length", "mask_width": "--mask-width", "seed": "--seed",
                    "key": "--key", "iv": "--iv"}


def _check_settings_apply(args, row):
    """Refuse an option that would be ignored: a setting ``row``'s mode does not read, or
    --grid without --times."""
    given = getattr(args, "given", frozenset())
    for name, option in _SETTING_OPTIONS.items():
        if name in given and name not in row.needs:
            reads = ", ".join(_SETTING_OPTIONS[need] for need in row.needs) or "no setting"
            raise ValueError(f"{option} is not a setting of --mode {row.name}, which reads "
                             f"{reads}")
    if args.grid and not args.times:
        raise ValueError("--grid changes the fire times only: give --times with it")


def run_sequence(args):
    clock_hz, period = timing_from_args(args)
    if not 0 <= args.count <= MAX_COUNT:
        raise UserError(f"--count must be from 0 to {MAX_COUNT} (a line a pulse, made in memory),"
                        f" not {args.count}")
    try:
        mode = delay_model.parse_mode(args.mode)
        _check_settings_apply(args, MODES[mode])
        keyed = {}
        if MODES[mode].keyed:
            if args.key is None or args.iv is None:
                raise ValueError(f"--mode {args.mode} needs --key and --iv")
            keyed = dict(key=parse_hex(args.key, "key", exact=True),
                         iv=parse_hex(args.iv, "IV"))
        settings = scheduler_model.Settings(
            mode=mode, length=args.length,
            mask_width=args.mask_width, seed=args.seed, period=period, grid=args.grid,
            pulse_width=args.pulse_width, **keyed).check()
        delays = settings.delays(args.count)
    except ValueError as error:
        raise UserError(str(error)) from None
    if args.times:
        values = scheduler_model.fire_cycles(delays, period, grid=args.grid) + \
            scheduler_model.LATENCY
    else:
        values = delays
    out = sys.stdout
    np.savetxt(out, values, fmt="%d")
