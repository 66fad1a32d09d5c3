"""``fliss prf-table``: the effective PRF of each delay source (Table 2 of the paper)."""

from ...hdl.delay.modes import MODES, SIZES
from ...sim.models.scheduler import prf_rows
from ..errors import UserError
from ..units import format_frequency
from .common import add_timing_options, timing_from_args


__all__ = ["register", "run_prf_table"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "prf-table", formatter_class=formatter,
        help="effective PRF for each delay source (Table 2 of the paper)",
        description="Effective PRF, equation 4: f_clk / (T + E(T_rnd)), with T = round(f_clk / "
                    "PRF) cycles. Sequences of up to 2**20 pulses are also generated and "
                    "measured.")
    add_timing_options(parser)
    parser.add_argument("--lengths", type=int, nargs="*", default=[3, 4, 5, 6, 8, 16, 32],
                        metavar="L", help=f"register lengths of {_sized('length')}")
    parser.add_argument("--mask-widths", type=int, nargs="*", default=[], metavar="W",
                        help=f"mask widths of {_sized('mask_width')}")
    parser.add_argument("--grid", action="store_true",
                        help="grid scheduler mode: pulse k at k*T + delay (needs the largest "
                             "delay to fit in the period)")
    parser.set_defaults(run=run_prf_table)


def _sized(size):
    # "the masked and keyed sources": the modes the setting `size` sizes
    *names, last = [row.name for row in MODES.values() if row.size == size]
    return f"the {', '.join(names)} and {last} sources" if names else f"the {last} source"


def run_prf_table(args):
    clock_hz, period = timing_from_args(args)
    try:
        rows = prf_rows(clock_hz, period, {"length": args.lengths,
                                           "mask_width": args.mask_widths}, grid=args.grid)
    except ValueError as error:
        raise UserError(str(error)) from None
    print(f"clock {format_frequency(clock_hz)}, nominal PRF {format_frequency(clock_hz / period)}"
          f" (T = {period} cycles), {'grid' if args.grid else 'interval'} mode")
    print(f"{'source':<8} {'setting':<8} {'max delay':>12} {'mean delay':>14} "
          f"{'PRF_eff (eq. 4)':>16} {'measured':>12}")
    for mode, setting, max_delay, mean_delay, closed, measured in rows:
        (size, value), = setting.items()
        name = f"{SIZES[size].symbol}={value}"
        print(f"{mode:<8} {name:<8} {max_delay:>12} {float(mean_delay):>14.6g} "
              f"{format_frequency(closed):>16} "
              f"{format_frequency(measured) if measured is not None else '-':>12}")
