"""The kinds of board settings (:class:`Kind`): how a value with units becomes register values
for a given clock, and back. The table of settings that uses them is
:data:`fliss.host.settings.OPTIONS` (read from the register map, which names each register's
kind: :data:`BY_KIND` maps the names to the kinds); its rules are told there.

A converter gets the :class:`~fliss.host.settings.Option`, the value as given and a
:class:`Context` (the clock, the registers so far, the notes), and returns
``{register: value}``; it refuses a value with :func:`refuse`, which names the setting as the
caller spelled it.
"""

import operator
import re
import secrets
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Mapping

from ..hdl.clock import MIN_PERIOD_CYCLES, period_cycles
from ..hdl.registers import BY_NAME, value_of, words_of
from ..hdl.register_rows import KINDS
from ..hdl.codes import code_s as timestamp_code_s
from ..hdl.delay.settings import as_int, parse_hex
from .errors import SettingsError
from .units import format_frequency, format_time, parse_frequency, parse_time


__all__ = ["Kind", "Context", "said", "BY_KIND", "WHOLE", "CHOICE", "TIME", "FREQUENCY", "GATE", "KEY", "IV",
           "PIXELS", "PIXEL", "MAX_PIXELS", "refuse", "code_s", "exact_time", "exact_frequency"]

#: Relative difference below which a value counts as a whole number of cycles (no note).
_EXACT = 1e-6


@dataclass(frozen=True)
class Kind:
    """How a setting's value becomes register values, and back.

    ``convert(option, value, context)`` returns ``{register: value}`` (several registers for a
    setting wider than one); ``show(option, registers, clock_hz)`` gives the value in units.
    """
    convert: Callable[[Any, Any, "Context"], Dict[str, int]]
    show: Callable[[Any, Mapping[str, int], int], Any]


@dataclass
class Context:
    """What a converter needs beyond the value: the clock, every register so far (changes
    applied), how to name settings (``"flag"`` or ``"keyword"``), and the notes made."""
    clock_hz: int
    registers: Dict[str, int]      # the settings so far, changes applied
    style: str
    notes: List[str] = field(default_factory=list)


def said(option, value, context):
    # How the caller wrote the setting: ``--integration 10ms`` or ``integration='10ms'``.
    if context.style == "flag":
        return f"{option.flag} {value}"
    return f"{option.name}={value!r}"


def refuse(option, value, context, message):
    """Raise the :exc:`~fliss.host.errors.SettingsError` for ``value`` of ``option``: the
    setting as the caller wrote it (``--mask-width 17``, ``mask_width=17``), then
    ``message``."""
    raise SettingsError(f"{said(option, value, context)}: {message}")


def _in_range(option, value, context, number, shown=None):
    # ``number`` if the register takes it; ``shown(n)`` writes a number with its units.
    register = BY_NAME[option.register]
    if not register.minimum <= number <= register.maximum:
        if shown is None:
            unit = f" {register.unit}" if register.unit else ""
            message = f"takes values from {register.minimum} to {register.maximum}{unit}"
            if str(number) != str(value).strip():
                message += f", not {number}"
        else:
            message = (f"takes values from {shown(register.minimum)} to "
                       f"{shown(register.maximum)}, not {shown(number)}")
        refuse(option, value, context, message)
    return number


# Kinds

def _whole_number(option, value, context):
    if isinstance(value, bool):
        refuse(option, value, context, "expected a whole number")
    if isinstance(value, str):
        try:
            return int(value.strip(), 0)
        except ValueError:
            refuse(option, value, context, "expected a whole number (0x for hex)")
    try:
        return operator.index(value)
    except TypeError:
        refuse(option, value, context, "expected a whole number")


def _convert_whole(option, value, context):
    number = _whole_number(option, value, context)
    return {option.register: _in_range(option, value, context, number)}


def _convert_choice(option, value, context):
    name = getattr(value, "name", value)        # an enum member: its name
    if isinstance(name, str) and name.strip().lower() in option.choices:
        return {option.register: option.choices[name.strip().lower()]}
    refuse(option, value, context, f"choose one of {', '.join(option.choices)}")


def _show_choice(option, registers, clock_hz):
    for name, number in option.choices.items():
        if number == registers[option.register]:
            return name
    return registers[option.register]


def _split_unit(value, unit):
    # ``"800cycles"`` -> ``"800"``; None when ``value`` does not end in ``unit``.
    if isinstance(value, str):
        match = re.fullmatch(rf"\s*(\S+?)\s*{unit}s?\s*", value, flags=re.IGNORECASE)
        if match:
            return match.group(1)
    return None


def _seconds(text):
    # parse_time, which also takes a zero time (a gate from 0 ns)
    match = re.fullmatch(r"\s*[-+]?0*\.?0*(e[-+]?\d+)?\s*([a-zµ]+)\s*", text, flags=re.IGNORECASE)
    if match and re.search(r"\d", text):
        parse_time("1" + match.group(2))      # a unit of time
        return 0.0
    return parse_time(text)


def _steps(option, value, context, step_s, step, example):
    """Whole steps (clock cycles, TDC codes) of ``step_s`` seconds from a time with unit or a
    number of steps (``"800cycles"``), with a note when rounded."""
    words = "clock cycle" if step == "cycle" else step
    count = _split_unit(value, step)
    if count is not None:
        return _whole_number(option, count, context)
    if not isinstance(value, str):
        refuse(option, value, context, f"give a unit: {example}")
    try:
        seconds = _seconds(value)
    except ValueError as error:
        message = str(error)
        if re.fullmatch(r"\s*[-+]?[\d.]+(e[-+]?\d+)?\s*", value, flags=re.IGNORECASE):
            message = f"give a unit: {example}"
        refuse(option, value, context, message)
    exact = seconds / step_s
    steps = round(exact)
    if steps < 1 and exact > 0 and option.register not in ("gate_start", "gate_end"):
        refuse(option, value, context, f"shorter than one clock cycle ({format_time(step_s)})")
    if abs(steps - exact) > _EXACT * max(1.0, exact):
        context.notes.append(f"{said(option, value, context)} is {exact:.4g} {words}s of "
                             f"{format_time(step_s)}: using {steps} {step}s, "
                             f"{format_time(steps * step_s)}")
    return steps


def _cycles_shown(clock_hz):
    return lambda n: f"{n} cycles ({format_time(n / clock_hz)})"


def _convert_time(option, value, context):
    cycles = _steps(option, value, context, 1 / context.clock_hz, "cycle", "10ms, or 800cycles")
    return {option.register: _in_range(option, value, context, cycles,
                                       _cycles_shown(context.clock_hz))}


def _show_time(option, registers, clock_hz):
    return exact_time(registers[option.register] / clock_hz)


def _convert_frequency(option, value, context):
    if isinstance(value, bool):
        refuse(option, value, context, "expected a frequency (1MHz)")
    try:
        hz = parse_frequency(value)
    except ValueError as error:
        refuse(option, value, context, str(error))
    exact = context.clock_hz / hz
    try:
        cycles = period_cycles(context.clock_hz, hz)
    except ValueError:
        refuse(option, value, context, f"too high for the board's "
                f"{format_frequency(context.clock_hz)} clock: the period must be at least "
                f"{MIN_PERIOD_CYCLES} cycles")
    if abs(cycles - exact) > _EXACT * exact:
        context.notes.append(f"{said(option, value, context)} is a period of {exact:.4g} clock "
                             f"cycles: using {cycles} cycles, "
                             f"{format_frequency(context.clock_hz / cycles)}")
    return {option.register: _in_range(option, value, context, cycles,
                                       _cycles_shown(context.clock_hz))}


def _show_frequency(option, registers, clock_hz):
    return exact_frequency(clock_hz / registers[option.register])


def code_s(registers: Mapping[str, int], clock_hz: int) -> float:
    """Seconds per timestamp code: the sensor TDC's LSB, a clock cycle for the coarse TDC, the
    fine TDC's LSB (:func:`fliss.hdl.codes.code_s`)."""
    return timestamp_code_s(registers, clock_hz)


def _convert_gate(option, value, context):
    step_s = code_s(context.registers, context.clock_hz)
    codes = _steps(option, value, context, step_s, "code", "100ns, or 2000codes")
    return {option.register: _in_range(option, value, context, codes,
                                       lambda n: f"{n} codes ({format_time(n * step_s)})")}


def _show_gate(option, registers, clock_hz):
    return exact_time(registers[option.register] * code_s(registers, clock_hz))


def _eighty_bits(option, value, context, what):
    # A key or IV: hex text as the test vectors print it, 10 bytes, or an 80-bit integer.
    try:
        if isinstance(value, str):
            return parse_hex(value, what)
        return as_int(value, what)
    except ValueError as error:
        refuse(option, value, context, str(error))


def _convert_key(option, value, context):
    """The key registers (write-only); ``"random"`` draws the key from the operating system's
    generator (:mod:`secrets`). The key is never shown; the caller finds it in the changes."""
    if isinstance(value, str) and value.strip().lower() == "random":
        key = int.from_bytes(secrets.token_bytes(10), "big")
    elif isinstance(value, str):
        # All 20 digits: a short key (12345) would be one nobody meant.
        try:
            key = parse_hex(value, "key", exact=True, alternative="random")
        except ValueError as error:
            refuse(option, value, context, str(error))
    else:
        key = _eighty_bits(option, value, context, "key")
    return words_of(key, "key")


def _convert_iv(option, value, context):
    """The IV registers. Writing the IV in use again changes nothing (so that a board's
    settings go back unchanged); another IV must be above it unless a key is written too
    (the register file refuses it otherwise: under one key no IV is used twice)."""
    iv = _eighty_bits(option, value, context, "IV")
    if iv == value_of(context.registers, "iv"):
        return {}
    return words_of(iv, "iv")


def _show_iv(option, registers, clock_hz):
    return f"{value_of(registers, 'iv'):020x}"


#: Pixel addresses of the sensor (6 bits): a frame holds at most this many pixels.
MAX_PIXELS = 1 << BY_NAME["pixel_bits"].maximum


def _nearest_power(number):
    # The power of two from 1 to MAX_PIXELS nearest ``number``, as text ("32 or 64" on a tie).
    powers = [1 << bits for bits in range(BY_NAME["pixel_bits"].maximum + 1)]
    best = min(abs(power - number) for power in powers)
    return " or ".join(str(power) for power in powers if abs(power - number) == best)


def _convert_pixels(option, value, context):
    """Pixels per frame, a power of two from 1 to 64, as ``pixel_bits``."""
    number = _whole_number(option, value, context)
    if number < 1 or number > MAX_PIXELS or number & (number - 1):
        refuse(option, value, context, f"takes a power of two from 1 to {MAX_PIXELS}; the "
                                       f"nearest is {_nearest_power(number)}")
    return {option.register: number.bit_length() - 1}


def _convert_pixel(option, value, context):
    """One pixel, at address ``value``: ``pixel_bits`` 0 and ``first_pixel`` the address (the
    single-pixel bench of the paper)."""
    number = _whole_number(option, value, context)
    if not 0 <= number < MAX_PIXELS:
        refuse(option, value, context, f"takes a pixel address from 0 to {MAX_PIXELS - 1}")
    return {"pixel_bits": 0, "first_pixel": number}


def _show_pixel(option, registers, clock_hz):
    return registers["first_pixel"] if registers["pixel_bits"] == 0 else None


WHOLE = Kind(_convert_whole, lambda option, registers, clock_hz: registers[option.register])
CHOICE = Kind(_convert_choice, _show_choice)
TIME = Kind(_convert_time, _show_time)
FREQUENCY = Kind(_convert_frequency, _show_frequency)
GATE = Kind(_convert_gate, _show_gate)
#: 80 bits in three registers, never shown (write-only).
KEY = Kind(_convert_key, lambda option, registers, clock_hz: None)
#: 80 bits in three registers; shows the IV in use.
IV = Kind(_convert_iv, _show_iv)
#: Pixels per frame (a power of two) as ``pixel_bits``; shows the number of pixels.
PIXELS = Kind(_convert_pixels, lambda option, registers, clock_hz: 1 << registers["pixel_bits"])
#: One pixel by its address: ``pixel_bits`` 0 and ``first_pixel``.
PIXEL = Kind(_convert_pixel, _show_pixel)

#: The converter of each kind the register map names (:data:`fliss.hdl.register_rows.KINDS`).
BY_KIND = {"whole": WHOLE, "choice": CHOICE, "time": TIME, "frequency": FREQUENCY, "gate": GATE,
           "key": KEY, "iv": IV, "pixels": PIXELS, "pixel": PIXEL}
assert set(BY_KIND) == set(KINDS)

def exact_time(seconds: float) -> str:
    """A time as text with an SI prefix and every digit that matters (``"154.3125 µs"``), so
    that it reads back as the same number of clock cycles."""
    for factor, prefix in ((1, ""), (1e-3, "m"), (1e-6, "µ"), (1e-9, "n")):
        if abs(seconds) >= factor:
            return f"{seconds / factor:.12g} {prefix}s"
    return f"{seconds / 1e-12:.12g} ps" if seconds else "0 s"


def exact_frequency(hz: float) -> str:
    """A frequency as text with an SI prefix and every digit that matters."""
    for factor, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if abs(hz) >= factor:
            return f"{hz / factor:.12g} {prefix}Hz"
    return f"{hz:.12g} Hz"
