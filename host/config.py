"""``fliss config``: show the board's registers, or set them by name with units."""

import argparse
import secrets

from ..hdl import period_cycles
from ..hdl.delay import DelayMode
from ..hdl.event import TDC_LSB_S
from ..sim.trivium import parse_hex
from ..hdl.registers import (REGISTERS, BY_NAME, AcquisitionMode, TdcSource, iv_problem,
                             value_of, words_of)
from .cli import UserError
from .port_options import add_port_arguments, connect
from .units import format_frequency, format_time, parse_frequency, parse_time


__all__ = ["register", "run", "changes_from_args", "describe", "parse_key", "keyed_changes"]


_MODES = [mode.name.lower() for mode in DelayMode]
_ON_OFF = {"on": 1, "off": 0}


def _number(text, what):
    try:
        return int(str(text), 0)
    except ValueError:
        raise UserError(f"{what}: expected a whole number, not {text!r}") from None


def _frequency(text, what):
    try:
        return parse_frequency(text)
    except ValueError as error:
        raise UserError(f"{what}: {error}") from None


def _cycles(text, clock_hz, what):
    """Clock cycles from a time with unit (``25ns``) or a plain number of cycles."""
    text = str(text).strip()
    if text.lower().endswith("cycles"):
        return _number(text[:-6].strip(), what)
    try:
        return int(text, 0)
    except ValueError:
        pass
    try:
        seconds = parse_time(text)
    except ValueError as error:
        raise UserError(f"{what}: {error}, or a number of clock cycles") from None
    cycles = round(seconds * clock_hz)
    if cycles < 1:
        raise UserError(f"{what}: {text} is shorter than one clock cycle "
                        f"({format_time(1 / clock_hz)})")
    return cycles


def _codes(text, code_s, what):
    """Timestamp codes from a time with unit or a plain number of codes."""
    text = str(text).strip()
    try:
        return int(text, 0)
    except ValueError:
        pass
    try:
        seconds = parse_time(text)
    except ValueError as error:
        raise UserError(f"{what}: {error}, or a number of TDC codes") from None
    return int(seconds / code_s)


def _period(text, clock_hz, what):
    try:
        return period_cycles(clock_hz, _frequency(text, what))
    except ValueError as error:
        raise UserError(f"{what}: {error}") from None


#: Setting flags: (flag, register, metavar, help). ``how`` converts the text.
def add_setting_arguments(parser):
    group = parser.add_argument_group(
        "settings (each changes one register; times take a unit, 25ns, or are clock cycles)")
    def add(*names, **kw):
        group.add_argument(*names, default=argparse.SUPPRESS, **kw)

    add("--acquisition", choices=["histogram", "raw"], help="what the board sends")
    add("--mode", choices=_MODES, help="victim delay source")
    add("--length", metavar="L", help="register length of the mseq source (bits)")
    add("--mask-width", metavar="WM", help="mask width of the masked source (bits)")
    add("--seed", metavar="S", help="non-zero seed of the victim delay source (0x for hex)")
    add("--prf", metavar="HZ", help="nominal pulse repetition frequency (1MHz): sets the period")
    add("--period-cycles", metavar="N", help="nominal laser period in clock cycles")
    grid = group.add_mutually_exclusive_group()
    grid.add_argument("--grid", dest="grid", action="store_const", const=1,
                      default=argparse.SUPPRESS, help="grid scheduler: pulse k at k T + R")
    grid.add_argument("--interval", dest="grid", action="store_const", const=0,
                      default=argparse.SUPPRESS, help="interval scheduler: pulses T + R apart")
    add("--pulse-width", metavar="TIME", help="laser trigger pulse width (25ns)")
    add("--aggressor", choices=["on", "off"], help="aggressor emitter")
    add("--aggressor-prf", metavar="HZ", help="aggressor pulse repetition frequency")
    add("--aggressor-period-cycles", metavar="N", help="aggressor period in clock cycles")
    add("--aggressor-offset", metavar="TIME", help="aggressor offset after the victim (75ns)")
    add("--aggressor-width", metavar="TIME", help="aggressor trigger pulse width")
    add("--aggressor-mode", choices=_MODES, help="aggressor's own delay source")
    add("--aggressor-length", metavar="L", help="aggressor mseq register length (bits)")
    add("--aggressor-mask-width", metavar="WM", help="aggressor mask width (bits)")
    add("--aggressor-seed", metavar="S", help="aggressor delay source seed")
    add("--tdc", choices=["sensor", "coarse"],
        help="event source: the sensor's timestamp bus or the built-in coarse TDC")
    add("--gate-start", metavar="TIME",
        help="first timestamp accepted (time from the TDC start, or codes)")
    add("--gate-end", metavar="TIME", help="last timestamp accepted (time, or codes)")
    add("--bin-shift", metavar="N", help="histogram bins are 2**N codes wide")
    add("--integration", metavar="TIME", help="histogram integration time (10ms)")
    _add_keyed_arguments(add)


# Keyed source: key and IV flags and their conversion (one block, to move as a whole)

def parse_key(text, what):
    """An 80-bit key or IV from hex (:func:`fliss.sim.trivium.parse_hex`); one line if not."""
    try:
        return parse_hex(text, "key" if what == "--key" else "IV")
    except ValueError as error:
        raise UserError(f"{what}: {error}") from None


def _add_keyed_arguments(add):
    add("--key", metavar="HEX|random",
        help="key of the keyed source: 20 hex digits, or 'random' (from the operating "
             "system's generator, never printed unless --show-key); write-only on the board")
    add("--iv", metavar="HEX", help="IV of the keyed source (20 hex digits); without --key it "
                                    "must be above the IV in use")
    add("--show-key", action="store_true", help="print the key written (with --key)")


def keyed_changes(args, current):
    """Register changes of ``--key`` and ``--iv``; a random key is left in ``args.key_value``
    (for ``--show-key``), never printed here. Refuses an IV the board would refuse."""
    changes = {}
    key = getattr(args, "key", None)
    if key is not None:
        value = int.from_bytes(secrets.token_bytes(10), "big") if key == "random" \
            else parse_key(key, "--key")
        args.key_value = value
        changes.update(words_of(value, "key"))
    if getattr(args, "iv", None) is not None:
        changes.update(words_of(parse_key(args.iv, "--iv"), "iv"))
        problem = iv_problem(changes, {**current, **changes}, value_of(current, "iv"))
        if problem:
            raise UserError(f"--iv: {problem} (give a higher --iv or a new --key)")
    return changes


def changes_from_args(args, current, clock_hz):
    """Register changes by name from the setting flags, converted with ``clock_hz``."""
    def get(name):
        return getattr(args, name, None)

    changes = {}
    if get("acquisition") is not None:
        changes["acquisition"] = AcquisitionMode[args.acquisition.upper()].value
    if get("mode") is not None:
        changes["delay_mode"] = DelayMode[args.mode.upper()].value
    for flag, name in (("length", "length"), ("mask_width", "mask_width"), ("seed", "seed"),
                       ("aggressor_length", "aggressor_length"),
                       ("aggressor_mask_width", "aggressor_mask_width"),
                       ("aggressor_seed", "aggressor_seed"), ("bin_shift", "bin_shift"),
                       ("period_cycles", "period"),
                       ("aggressor_period_cycles", "aggressor_period")):
        if get(flag) is not None:
            changes[name] = _number(get(flag), "--" + flag.replace("_", "-"))
    if get("prf") is not None:
        changes["period"] = _period(args.prf, clock_hz, "--prf")
    if get("aggressor_prf") is not None:
        changes["aggressor_period"] = _period(args.aggressor_prf, clock_hz, "--aggressor-prf")
    if get("grid") is not None:
        changes["grid"] = args.grid
    for flag, name in (("pulse_width", "pulse_width"), ("aggressor_offset", "aggressor_offset"),
                       ("aggressor_width", "aggressor_width"), ("integration", "integration")):
        if get(flag) is not None:
            changes[name] = _cycles(get(flag), clock_hz, "--" + flag.replace("_", "-"))
    if get("aggressor") is not None:
        changes["aggressor"] = _ON_OFF[args.aggressor]
    if get("aggressor_mode") is not None:
        changes["aggressor_delay_mode"] = DelayMode[args.aggressor_mode.upper()].value
    if get("tdc") is not None:
        changes["tdc_source"] = TdcSource[args.tdc.upper()].value
    source = changes.get("tdc_source", current["tdc_source"])
    code_s = 1 / clock_hz if source == TdcSource.COARSE.value else TDC_LSB_S
    for flag in ("gate_start", "gate_end"):
        if get(flag) is not None:
            changes[flag] = _codes(get(flag), code_s, "--" + flag.replace("_", "-"))
    changes.update(keyed_changes(args, current))
    return changes


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
        return AcquisitionMode(value).name.lower() if value in (0, 1) else "?"
    if name == "tdc_source":
        return TdcSource(value).name.lower() if value in (0, 1) else "?"
    if name in ("grid",):
        return "grid" if value else "interval"
    if name == "aggressor":
        return "on" if value else "off"
    if name in ("gate_start", "gate_end"):
        code_s = cycle_s if settings.get("tdc_source") == TdcSource.COARSE.value else TDC_LSB_S
        return format_time(value * code_s) if value else "0 s"
    if name == "bin_shift":
        return f"{1 << value} codes per bin"
    if name in ("seed", "aggressor_seed"):
        return f"{value:#x}"
    if BY_NAME[name].write_only:
        return "write-only"
    if name == "iv0":
        return f"IV in use {value_of(settings, 'iv'):#022x}"
    return ""


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
    add_setting_arguments(parser)
    parser.set_defaults(run=run)


def run(args):
    with connect(args) as board:
        clock_hz = board.identity.clock_hz
        current = board.read_registers()
        changes = changes_from_args(args, current, clock_hz)
        if changes:
            board.write_registers(changes, current=current)
            current = board.read_registers()
            changed = [name for name in changes if current[name] != changes[name] and
                       not BY_NAME[name].write_only and not BY_NAME[name].in_use]
            if changed:
                raise UserError(f"the board did not keep {', '.join(changed)}")
    identity = board.identity
    if getattr(args, "show_key", False) and hasattr(args, "key_value"):
        print(f"key {args.key_value:#022x}")
    print(f"board on {args.port}: gateware {identity.gateware_version}, protocol "
          f"{identity.protocol}, clock {format_frequency(clock_hz)}, "
          f"{identity.baud} baud")
    print(f"{'register':<22} {'value':>10} {'unit':<7} {'':<22} meaning")
    for register in REGISTERS:
        value = current[register.name]
        mark = "*" if register.name in changes else " "
        print(f"{register.name:<22}{mark}{value:>10} {register.unit:<7} "
              f"{describe(register.name, value, current, clock_hz):<22} {register.doc}")
    return 0
