"""``fliss config``: show the board's registers, or set them by name with units."""

import sys

from ..errors import UserError
from ...hdl.registers import REGISTERS, value_of
from .port_options import add_port_arguments, connect
from .setting_options import add_setting_arguments, settings_from_args
from ..settings import check_offline
from ..setting_display import describe
from ..units import format_frequency


__all__ = ["register", "run", "describe"]

#: Title of the setting flags in ``--help``.
SETTINGS_TITLE = ("settings (each changes one register; times take a unit, 25ns, or are whole "
                  "clock cycles, 2cycles; values are rounded to whole cycles, with a warning)")


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
