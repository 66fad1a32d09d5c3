"""How ``fliss config`` shows a register's value: in physical units, or by its meaning.

The register map's row says how (:class:`fliss.hdl.register_rows.Row` ``display``): by its kind
(a time, a period with its frequency, a gate time in TDC codes, a choice by name, ...), by a
table of texts, by a format (``"{value:#x}"``), or by the name of one of the displays here that
read other registers (the bin width, the pixels, the filter's time, the IV in use).
"""

from ..hdl.codes import code_s
from ..hdl.event import TIMESTAMP_BITS
from ..hdl.registers import BY_NAME, value_of
from .units import format_frequency, format_time


__all__ = ["describe"]


def _choice(register, value, settings, clock_hz):
    names = [name for name, number in register.choices.items() if number == value]
    return names[0] if names else "?"


def _time(register, value, settings, clock_hz):
    return format_time(value / clock_hz)


def _frequency(register, value, settings, clock_hz):
    return f"{format_time(value / clock_hz)} ({format_frequency(clock_hz / value)})"


def _gate(register, value, settings, clock_hz):
    return format_time(value * code_s(settings, clock_hz)) if value else "0 s"


def _pixels(register, value, settings, clock_hz):
    return f"{1 << value} pixel{'s' if value else ''} per frame"


def _key(register, value, settings, clock_hz):
    return "write-only"


def _nothing(register, value, settings, clock_hz):
    return ""


#: The display of each kind (:data:`fliss.hdl.register_rows.KINDS`).
_BY_KIND = {"whole": _nothing, "choice": _choice, "time": _time, "frequency": _frequency,
            "gate": _gate, "key": _key, "iv": _nothing, "pixels": _pixels, "pixel": _nothing}


def _bin_width(register, value, settings, clock_hz):
    bins = (1 << TIMESTAMP_BITS) >> value
    return f"bins of {format_time((1 << value) * code_s(settings, clock_hz))}, {bins} per pixel"


def _pixel_range(register, value, settings, clock_hz):
    last = value + (1 << settings.get("pixel_bits", 0)) - 1
    return f"pixels {value} to {last}" if last != value else f"pixel {value}"


def _filter_width(register, value, settings, clock_hz):
    bin_s = (1 << settings.get("bin_shift", 0)) * code_s(settings, clock_hz)
    return f"{value} bins, {format_time(value * bin_s)}"


def _iv_in_use(register, value, settings, clock_hz):
    return f"IV in use {value_of(settings, 'iv'):#022x}"


#: The displays a row names.
_NAMED = {"bin_width": _bin_width, "pixel_range": _pixel_range, "filter_width": _filter_width,
          "iv_in_use": _iv_in_use}


def describe(name, value, settings, clock_hz):
    """The value of register ``name`` in physical units, or its meaning, as text
    (``settings``: every register's value, for the displays that read others)."""
    register = BY_NAME[name]
    display = register.display
    if display is None:
        return _BY_KIND[register.kind](register, value, settings, clock_hz)
    if isinstance(display, dict):
        return display.get(value, "?")
    if "{" in display:
        return display.format(value=value)
    return _NAMED[display](register, value, settings, clock_hz)
