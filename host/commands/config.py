"""``fliss config``: show the board's registers, or set them by name with units."""

import sys

from ..errors import UserError
from ...hdl.delay.source import DelayMode
from ...hdl.event import TIMESTAMP_BITS
from ...hdl.codes import code_s
from ...hdl.registers import REGISTERS, BY_NAME, AcquisitionMode, TdcSource, value_of
from .port_options import add_port_arguments, connect
from .setting_options import add_setting_arguments, settings_from_args
from ..settings import check_offline
from ..units import format_frequency, format_time


__all__ = ["register", "run", "describe"]

#: Title of the setting flags in ``--help``.
SETTINGS_TITLE = ("settings (each changes one register; times take a unit, 25ns, or are whole "
                  "clock cycles, 2cycles; values are rounded to whole cycles, with a warning)")


def describe(name, value, settings, clock_hz):
    """The value of a register in physical units, or its meaning, as text."""
    cycle_s = 1 / clock_hz
    if name in ("period", "aggressor_period"):
        return f"{format_time(value * cycle_s)} ({format_frequency(clock_hz / value)})"
    if name in ("pulse_width", "aggressor_offset", "aggressor_width", "integration"):
        return format_time(value * cycle_s)
    if name in ("delay_mode", "aggressor_delay_mode"):
        try:
            return DelayMode(value).name.lower()
        except ValueError:
            return "?"
    if name == "acquisition":
        modes = {mode.value: mode.name.lower() for mode in AcquisitionMode}
        return modes.get(value, "?")
    if name == "tdc_source":
        return TdcSource(value).name.lower() if value in {s.value for s in TdcSource} else "?"
    if name in ("grid",):
        return "grid" if value else "interval"
    if name == "aggressor":
        return "on" if value else "off"
    if name in ("gate_start", "gate_end"):
        return format_time(value * _code_s(settings, clock_hz)) if value else "0 s"
    if name == "bin_shift":
        bins = (1 << TIMESTAMP_BITS) >> value
        return f"bins of {format_time((1 << value) * _code_s(settings, clock_hz))}, {bins} per pixel"
    if name == "pixel_bits":
        return f"{1 << value} pixel{'s' if value else ''} per frame"
    if name == "first_pixel":
        last = value + (1 << settings.get("pixel_bits", 0)) - 1
        return f"pixels {value} to {last}" if last != value else f"pixel {value}"
    if name == "collisions":
        return "drop (counted)" if value else "keep"
    if name == "full_readout":
        return "full" if value else "compact"
    if name == "depth_filter":
        bin_s = (1 << settings.get("bin_shift", 0)) * _code_s(settings, clock_hz)
        return f"{value} bins, {format_time(value * bin_s)}"
    if name == "depth_threshold":
        return f"{value} counts"
    if name in ("seed", "aggressor_seed"):
        return f"{value:#x}"
    if BY_NAME[name].write_only:
        return "write-only"
    if name == "iv0":
        return f"IV in use {value_of(settings, 'iv'):#022x}"
    return ""


def _code_s(settings, clock_hz):
    # Seconds per timestamp code (the coarse TDC's, the fine TDC's or the sensor's)
    return code_s(settings, clock_hz)


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "config", formatter_class=formatter,
        help="show the board's registers, or set them with units",
        description="Without settings, prints every register with its value, unit and meaning. "
                    "With settings, checks them on the host (range and consistency, as the "
                    "gateware does), writes them in one WRITE (all applied or none), and prints "
                    "the registers read back. Times are converted to clock cycles with the "
                    "board's clock frequency from its identity.")
    add_port_arguments(parser)
    add_setting_arguments(parser, SETTINGS_TITLE)
    parser.add_argument("--show-key", action="store_true",
                        help="print the key written by --key (a random one is otherwise never "
                             "shown)")
    parser.set_defaults(run=run)


def _warn_if_running(board):
    from ..acquisition import left_running
    warning = left_running(board.client, "`fliss capture` stops it (and starts it again)")
    if warning:
        print(f"fliss: warning: {warning}", file=sys.stderr)


def run(args):
    if args.show_key and "key" not in getattr(args, "given", {"key"}):
        raise UserError("--show-key prints the key this command writes: give --key with it "
                        "(a key on the board is never read back)")
    check_offline(settings_from_args(args))     # before the board: wrong on any board
    with connect(args) as board:
        _warn_if_running(board)
        clock_hz = board.clock_hz
        conversion = board.configure(settings_from_args(args), style="flag")
        changes, current = conversion.changes, board.registers
    identity = board.identity
    if args.show_key and "key0" in changes:
        print(f"key {value_of(changes, 'key'):#022x}")
    print(f"board on {args.port}: gateware {identity.gateware_version}, protocol "
          f"{identity.protocol}, clock {format_frequency(clock_hz)}, "
          f"{identity.baud} baud")
    print(f"{'register':<22} {'value':>10} {'unit':<7} {'':<30} meaning")
    for register in REGISTERS:
        value = current[register.name]
        mark = "*" if register.name in changes else " "
        print(f"{register.name:<22}{mark}{value:>10} {register.unit:<7} "
              f"{describe(register.name, value, current, clock_hz):<30} {register.doc}")
    return 0
