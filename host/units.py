"""Quantities with units on the command line: ``80MHz``, ``1e6``, ``75ns``, ``10ms``."""

import math
import re


__all__ = ["parse_frequency", "parse_time", "parse_baud", "parse_length", "parse_angle",
           "format_frequency", "format_time"]


_NUMBER = r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)"

_FREQUENCY = {"hz": 1, "khz": 1e3, "mhz": 1e6, "ghz": 1e9}
_TIME = {"s": 1, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "ns": 1e-9, "ps": 1e-12}


def _parse(text, units, what, example, zero=False):
    match = re.fullmatch(_NUMBER + r"\s*([a-zµ°]*)", str(text).strip(), flags=re.IGNORECASE)
    if match is not None and not match.group(2) and "" not in units:
        raise ValueError(f"give a unit: {example}")
    if match is None or match.group(2).lower() not in units:
        raise ValueError(f"cannot read {text!r} as a {what} (for example {example})")
    value = float(match.group(1)) * units[match.group(2).lower()]
    if math.isinf(value):
        raise ValueError(f"{what} {text!r} is beyond any number a computer holds")
    if zero and not value >= 0:
        raise ValueError(f"{what} must not be negative, not {text!r}")
    if not zero and not value > 0:
        raise ValueError(f"{what} must be positive, not {text!r}")
    return value


def parse_frequency(text):
    """Frequency in Hz from ``"80MHz"``, ``"1 kHz"``, ``"2.5e6Hz"``; the unit is required (a
    bare ``1`` would be 1 Hz, a period of 80 million cycles, when 1 MHz was meant)."""
    value = _parse(text, _FREQUENCY, "frequency", "80MHz, 1kHz or 1e6Hz")
    return int(value) if value == int(value) else value


def parse_time(text, *, zero=False):
    """Time in seconds from ``"10ms"``, ``"75ns"``, ``"1.5s"``; the unit is required. A time
    must be positive, or with ``zero`` not negative (``"0ns"``: the TDC start)."""
    return _parse(text, _TIME, "time", "10ms or 75ns", zero=zero)


_BAUD = {"": 1, "k": 1e3, "m": 1e6, "kbaud": 1e3, "mbaud": 1e6, "baud": 1, "bd": 1}


def parse_baud(text):
    """Baud rate from ``"3M"``, ``"12Mbaud"``, ``"115200"``."""
    value = _parse(text, _BAUD, "baud rate", "115200, 3M or 12Mbaud")
    if value != int(value):
        raise ValueError(f"baud rate must be a whole number, not {text!r}")
    return int(value)


_LENGTH = {"m": 1, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "nm": 1e-9}
_ANGLE = {"deg": math.pi / 180, "°": math.pi / 180, "rad": 1, "mrad": 1e-3}


def parse_length(text):
    """Length in metres from ``"30um"``, ``"2.5mm"``; the unit is required; positive."""
    return _parse(text, _LENGTH, "length", "30um or 2.5mm")


def parse_angle(text):
    """Angle in radians from ``"40deg"``, ``"0.7rad"``; the unit is required; positive."""
    return _parse(text, _ANGLE, "angle", "40deg or 0.7rad")


def format_frequency(hz):
    """``963.9 kHz`` style: four significant figures and an SI prefix."""
    hz = float(hz)
    for factor, prefix in ((1e9, "G"), (1e6, "M"), (1e3, "k"), (1, ""), (1e-3, "m")):
        if abs(hz) >= factor:
            return f"{hz / factor:.4g} {prefix}Hz"
    return f"{hz:.4g} Hz"


def format_time(seconds):
    """``12.5 ns`` style: four significant figures and an SI prefix."""
    if seconds == 0:
        return "0 s"
    for factor, prefix in ((1, ""), (1e-3, "m"), (1e-6, "µ"), (1e-9, "n")):
        if abs(seconds) >= factor:
            return f"{seconds / factor:.4g} {prefix}s"
    return f"{seconds / 1e-12:.4g} ps"
