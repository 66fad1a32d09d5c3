"""Model commands: ``fliss prf-table`` and ``fliss sequence``."""

import sys

import numpy as np

from ..hdl import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles
from ..sim import delay as delay_model
from ..sim import scheduler as scheduler_model
from ..sim import trivium
from .cli import UserError
from .units import parse_frequency, format_frequency


#: Whole sequences up to this many pulses are also measured by generating them.
MEASURE_LIMIT = 1 << 20


def _frequency(text):
    try:
        return parse_frequency(text)
    except ValueError as error:
        raise UserError(str(error)) from None


def _period(args):
    clock_hz = _frequency(args.clock)
    prf_hz = _frequency(args.prf)
    try:
        return clock_hz, period_cycles(clock_hz, prf_hz)
    except ValueError as error:
        raise UserError(str(error)) from None


def _add_timing(parser):
    parser.add_argument("--clock", default=f"{DEFAULT_CLOCK_HZ // 1_000_000}MHz", metavar="HZ",
                        help="system clock frequency (80MHz, 79.5e6, ...)")
    parser.add_argument("--prf", default=f"{DEFAULT_PRF_HZ // 1_000_000}MHz", metavar="HZ",
                        help="nominal pulse repetition frequency")


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "prf-table", formatter_class=formatter,
        help="effective PRF for each delay source (Table 2 of the paper)",
        description="Effective PRF, equation 4: f_clk / (T + E(T_rnd)), with T = round(f_clk / "
                    "PRF) cycles. Sequences of up to 2**20 pulses are also generated and "
                    "measured.")
    _add_timing(parser)
    parser.add_argument("--lengths", type=int, nargs="*", default=[3, 4, 5, 6, 8, 16, 32],
                        metavar="L", help="register lengths of the mseq source")
    parser.add_argument("--mask-widths", type=int, nargs="*", default=[], metavar="W",
                        help="mask widths of the masked source")
    parser.add_argument("--grid", action="store_true",
                        help="grid scheduler mode: pulse k at k*T + delay (needs the largest "
                             "delay to fit in the period)")
    parser.set_defaults(run=run_prf_table)

    parser = subparsers.add_parser(
        "sequence", formatter_class=formatter,
        help="print the delays (or laser fire times) of a delay source",
        description="One delay in clock cycles per line, exactly as the gateware produces them "
                    "after a start; with --times, the cycle of each laser rising edge counted "
                    "from the first frame.")
    parser.add_argument("--mode", default="mseq", choices=["off", "mseq", "masked", "keyed"],
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
    parser.add_argument("--seed", type=lambda text: int(text, 0), default=1, metavar="S",
                        help="non-zero register seed (decimal or 0x hex)")
    parser.add_argument("--count", type=int, default=16, metavar="N", help="number of pulses")
    parser.add_argument("--times", action="store_true",
                        help="print laser fire times in clock cycles instead of delays")
    parser.add_argument("--grid", action="store_true",
                        help="grid scheduler mode (pulse k at k*T + delay) for --times")
    parser.add_argument("--pulse-width", type=int, default=1, metavar="CYCLES",
                        help="laser pulse width in clock cycles, checked against the period")
    _add_timing(parser)
    parser.set_defaults(run=run_sequence)


def prf_rows(clock_hz, period, lengths=(), mask_widths=(), *, grid=False):
    """Rows of the PRF table: (source, setting, max delay, mean delay, PRF closed form,
    PRF measured or None)."""
    rows = []
    sources = [("mseq", {"length": length}) for length in lengths] + \
              [("masked", {"mask_width": width}) for width in mask_widths]
    for mode, setting in sources:
        max_delay = delay_model.max_delay(mode, **setting)
        mean_delay = delay_model.mean_delay(mode, **setting)
        if grid:
            scheduler_model.check_schedule(period, 1, grid=True, max_delay=max_delay)
        closed = scheduler_model.effective_prf(clock_hz, period, mean_delay, grid=grid)
        pulses = delay_model.sequence_period(mode, **setting)
        measured = None
        if pulses <= MEASURE_LIMIT:
            delays = delay_model.delays(mode, pulses + 1, **setting)
            measured = scheduler_model.measured_prf(
                clock_hz, scheduler_model.fire_cycles(delays, period, grid=grid))
        rows.append((mode, setting, max_delay, mean_delay, closed, measured))
    return rows


def run_prf_table(args):
    clock_hz, period = _period(args)
    try:
        rows = prf_rows(clock_hz, period, args.lengths, args.mask_widths, grid=args.grid)
    except ValueError as error:
        raise UserError(str(error)) from None
    print(f"clock {format_frequency(clock_hz)}, nominal PRF {format_frequency(clock_hz / period)}"
          f" (T = {period} cycles), {'grid' if args.grid else 'interval'} mode")
    print(f"{'source':<8} {'setting':<8} {'max delay':>12} {'mean delay':>14} "
          f"{'PRF_eff (eq. 4)':>16} {'measured':>12}")
    for mode, setting, max_delay, mean_delay, closed, measured in rows:
        name = f"L={setting['length']}" if "length" in setting else f"Wm={setting['mask_width']}"
        print(f"{mode:<8} {name:<8} {max_delay:>12} {float(mean_delay):>14.6g} "
              f"{format_frequency(closed):>16} "
              f"{format_frequency(measured) if measured is not None else '-':>12}")


def run_sequence(args):
    clock_hz, period = _period(args)
    if args.count < 0:
        raise UserError(f"--count must not be negative, not {args.count}")
    try:
        keyed = {}
        if args.mode == "keyed":
            if args.key is None or args.iv is None:
                raise ValueError("--mode keyed needs --key and --iv")
            keyed = dict(key=trivium.parse_hex(args.key, "key"),
                         iv=trivium.parse_hex(args.iv, "IV"))
        settings = scheduler_model.Settings(
            mode=delay_model.parse_mode(args.mode), length=args.length,
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
