"""Board settings with units: ``{"integration": "10ms", "mode": "masked"}`` as register values.

:data:`OPTIONS` says for each setting its name (a keyword of
:meth:`fliss.host.board.Board.configure`, and with ``--`` and dashes the flag of ``fliss config``
and ``fliss capture``), the register it sets and its :class:`Kind`: how a value with units
becomes a register value for a given clock, and back (the kinds: :mod:`fliss.host.setting_kinds`).
It is read from the register map's rows (:data:`fliss.hdl.registers.ROWS`), which name each
register's kind, keywords, help and choices: a new setting is a keyword of a row; one wider than
a register (a key) is one keyword whose kind returns several registers.

The rules, the same in the library and on the command line:

* A time takes a unit: ``"10ms"``, ``"75 ns"``, or whole clock cycles, ``"800cycles"`` (gate
  times: TDC codes, ``"2000codes"``). A bare number is refused (``10`` could be cycles, seconds
  or milliseconds). A frequency takes a unit too (``"1MHz"``, ``"1e6Hz"``): a bare ``1`` would
  be 1 Hz, a period of 80 million cycles.
* A time or frequency that is not a whole number of clock cycles (codes) is rounded to the
  nearest; :func:`convert` returns a note for each, one line with the value used
  (``--aggressor-offset 80ns is 6.4 clock cycles of 12.5 ns: using 6 cycles, 75 ns``).
* Refusals raise :exc:`~fliss.host.errors.SettingsError` naming the setting as the caller spells
  it (``style="flag"``: ``--mask-width``; ``style="keyword"``: ``mask_width``), with units.
"""

import re
from dataclasses import dataclass, field
from typing import Any, Dict, List, Mapping, Optional, Tuple

import numpy as np

from ..hdl.event import TIMESTAMP_BITS
from ..hdl.clock import DEFAULT_CLOCK_HZ
from ..hdl.delay.settings import LAST_IV
from ..hdl.registers import BY_NAME, ROWS, defaults, iv_problem, problems, value_of
from .errors import SettingsError
from .imager.threshold import depth_threshold
from .setting_kinds import (BY_KIND, CHOICE, PIXEL, PIXELS, WHOLE, MAX_PIXELS, Context, Kind,
                            code_s, exact_frequency, exact_time, said)
from .units import format_frequency, format_time, parse_time


__all__ = ["RoundingWarning", "Kind", "Option", "OPTIONS", "BY_OPTION", "Conversion",
           "DEFAULT_BANK_BITS", "Settings", "convert", "check_offline", "split_problem",
           "describe", "duration_s", "exact_time", "exact_frequency",
           "code_s"]


class RoundingWarning(UserWarning):
    """A setting was rounded to whole clock cycles (TDC codes); the message says to what."""



@dataclass(frozen=True)
class Option:
    """One setting: a keyword, the register it sets, its :class:`Kind` and its help text.

    ``choices`` maps the names a choice takes to register values. ``shown`` is False for an
    alternative spelling of a register that another option shows (``period_cycles`` beside
    ``prf``): :class:`Settings` has one key per register.
    """
    name: str
    register: str
    kind: Kind
    help: str
    metavar: Optional[str] = None
    choices: Optional[Mapping[str, int]] = None
    shown: bool = True

    @property
    def flag(self) -> str:
        """The command-line flag: ``--mask-width``."""
        return "--" + self.name.replace("_", "-")

    def label(self, style: str) -> str:
        return self.flag if style == "flag" else self.name


def _after_reset(register):
    """``after reset: 1 cycle, 12.5 ns at 80 MHz``: a time register's reset value."""
    cycles = BY_NAME[register].reset_value(DEFAULT_CLOCK_HZ)
    return (f"after reset: {cycles} cycle{'' if cycles == 1 else 's'}, "
            f"{format_time(cycles / DEFAULT_CLOCK_HZ)} at {format_frequency(DEFAULT_CLOCK_HZ)}")


def _help(row, keyword):
    # The keyword's help, with the row's default (``10ms``) or reset value in it
    text = keyword.help
    if "{default}" in text:
        text = text.replace("{default}", str(row.reset).replace(" ", ""))
    if "{after_reset}" in text:
        text = text.replace("{after_reset}", _after_reset(row.name))
    return text


#: Every setting, in the order they are converted (``tdc`` and ``fine_lsb`` before the gate,
#: which depends on them) and shown: the keywords of the register map's rows
#: (:data:`fliss.hdl.registers.ROWS`), in its order.
OPTIONS: Tuple[Option, ...] = tuple(
    Option(keyword.name, row.name, BY_KIND[keyword.kind or row.kind], _help(row, keyword),
           keyword.metavar, keyword.choices or row.choices, keyword.shown)
    for row in ROWS for keyword in row.keywords)

#: The options by name.
BY_OPTION = {option.name: option for option in OPTIONS}


def duration_s(value: Any, label: str) -> float:
    """Seconds from a time with a unit (``"100ms"``) that is not a setting (how long to
    capture); a bare number is refused here too. ``label`` names it in the
    :exc:`~fliss.host.errors.SettingsError`: ``"--duration 1"`` or ``"duration=1"``."""
    if isinstance(value, str) and not re.fullmatch(r"\s*[-+]?[\d.]+(e[-+]?\d+)?\s*", value,
                                                   flags=re.IGNORECASE):
        try:
            return parse_time(value)
        except ValueError as error:
            raise SettingsError(f"{label}: {error}") from None
    raise SettingsError(f"{label}: give a unit: 100ms, or 2s")


@dataclass(frozen=True)
class Conversion:
    """What :func:`convert` made of some settings.

    Attributes
    ----------
    changes : dict
        Register values by register name, of the registers the settings set.
    registers : dict
        Every register: the current ones with ``changes`` applied (checked for consistency).
    notes : list of str
        One line for each value rounded to whole clock cycles (codes), with the value used.
    """
    changes: Dict[str, int]
    registers: Dict[str, int]
    notes: List[str]
    #: How the caller wrote the setting behind each changed register (``--mode keyed``).
    said: Dict[str, str] = field(default_factory=dict)


#: The registers of the pixel split: a change sets ``depth_threshold`` (:func:`convert`).
SPLIT = ("bin_shift", "pixel_bits")

#: The registers ``depth_threshold`` is set from: a threshold that a split set follows them.
THRESHOLD_INPUTS = SPLIT + ("integration", "period", "depth_filter")

#: Address bits of the histogram bank (bins of all pixels of a frame) until the board reports
#: its own: 16 on the ULX3S and the virtual board (64 pixels of 1024 bins), 14 on the iCEBreaker.
DEFAULT_BANK_BITS = 16


def convert(settings: Mapping[str, Any], clock_hz: int, current: Mapping[str, int], *,
            style: str = "keyword", bank_bits: int = DEFAULT_BANK_BITS) -> Conversion:
    """Register values from settings with units.

    Parameters
    ----------
    settings : mapping
        Setting name (:data:`OPTIONS`) to value: a string with units (``"10ms"``,
        ``"800cycles"``, ``"1MHz"``), a choice name (``"masked"``), a whole number, or None
        (left as it is).
    clock_hz : int
        The board's clock frequency (its identity).
    current : mapping
        Every register's current value (``BoardClient.read_registers()``).
    style : {"keyword", "flag"}
        How refusals and notes name a setting: ``mask_width=17`` or ``--mask-width 17``.
    bank_bits : int
        Address bits of the board's histogram bank: a split of ``2**pixel_bits`` pixels of
        ``2**(13 - bin_shift)`` bins fits when ``pixel_bits + 13 - bin_shift <= bank_bits``.

    Returns
    -------
    Conversion

    Raises
    ------
    SettingsError
        An unknown setting, a value that cannot be read or is out of range, two settings for
        one register, or settings that are not consistent (the checks of the gateware).
    """
    context = Context(int(clock_hz), dict(current), style)
    unknown = [name for name in settings if name not in BY_OPTION]
    if unknown:
        raise SettingsError(f"no setting named {unknown[0]!r} (settings: "
                            f"{', '.join(BY_OPTION)})")
    given = {name: value for name, value in settings.items() if value is not None}
    labels = {option.register: option.label(style) for option in OPTIONS if option.shown}
    changes, by, written = {}, {}, {}
    for option in OPTIONS:
        if option.name not in given:
            continue
        for register, value in option.kind.convert(option, given[option.name], context).items():
            if register in by:
                raise SettingsError(f"{by[register].label(style)} and {option.label(style)} "
                                    f"both set {register}: give one of them")
            by[register] = option
            labels[register] = option.label(style)
            changes[register] = value
            written[register] = said(option, given[option.name], context)
            context.registers[register] = value
    split = split_problem(context.registers, bank_bits, style, labels)
    if split:
        raise SettingsError(split)
    # A new pixel split gets the depth threshold that suits it, unless one is given with it (a
    # threshold for 8192 bins of one pixel detects nothing in 1024 bins of each of 64); one set
    # so follows the integration time, period and filter too.
    changed = {name for name in THRESHOLD_INPUTS if context.registers[name] != current[name]}
    if "depth_threshold" not in given and (changed & set(SPLIT) or changed and current[
            "depth_threshold"] == depth_threshold(current)):
        threshold = depth_threshold(context.registers)
        changes["depth_threshold"] = context.registers["depth_threshold"] = threshold
        written["depth_threshold"] = (f"{BY_OPTION['depth_threshold'].label(style)} {threshold}"
                                      f" (for the pixel split)")
    found = _problems(context.registers, labels, context.clock_hz, bank_bits)
    in_use = value_of(current, "iv")
    iv = iv_problem(changes, context.registers, in_use)
    if iv:
        remedy = "a new key" if in_use == LAST_IV else "a higher IV or a new key"
        found.append(f"{BY_OPTION['iv'].label(style)}: {iv} (give {remedy})")
    if found:
        raise SettingsError("; ".join(found))
    for name, value in changes.items():
        # (a choice the register map's row has, above a smaller range: the aggressor's keyed)
        try:
            BY_NAME[name].check(value)
        except ValueError as error:
            raise SettingsError(str(error)) from None
    return Conversion(changes, context.registers, context.notes, written)


def split_problem(registers: Mapping[str, int], bank_bits: int = DEFAULT_BANK_BITS,
                  style: str = "flag", labels: Optional[Mapping[str, str]] = None
                  ) -> Optional[str]:
    """One line saying why the pixel split of ``registers`` does not fit the histogram bank of
    ``bank_bits`` address bits, or the pixels go beyond the sensor's addresses, and what would
    fit; None when it fits."""
    def setting(name, value):
        return f"--{name.replace('_', '-')} {value}" if style == "flag" else f"{name}={value}"

    def codes(count):
        return f"{count} code{'s' if count != 1 else ''}"

    pixel_bits, shift = registers["pixel_bits"], registers["bin_shift"]
    pixels, bins = 1 << pixel_bits, (1 << TIMESTAMP_BITS) >> shift
    first = registers["first_pixel"]
    by_bits = labels is not None and labels.get("pixel_bits") in ("--pixel-bits", "pixel_bits")
    if pixel_bits + TIMESTAMP_BITS - shift > bank_bits:
        need = pixel_bits + TIMESTAMP_BITS - bank_bits
        most = min(1 << max(0, bank_bits - TIMESTAMP_BITS + shift), MAX_PIXELS)
        given = setting("pixel_bits", pixel_bits) if by_bits else setting("pixels", pixels)
        return (f"{given} with {setting('bin_shift', shift)} ({bins} bins of "
                f"{codes(1 << shift)} per pixel) does not fit the board's histogram memory of "
                f"{1 << bank_bits} bins: {pixels} pixels need bins of at least "
                f"{codes(1 << need)} ({setting('bin_shift', need)}); bins of "
                f"{codes(1 << shift)} fit at most {most} pixels ({setting('pixels', most)})")
    if first + pixels > MAX_PIXELS:
        return (f"{setting('first_pixel', first)} with {pixels} pixels reaches "
                f"address {first + pixels - 1}, beyond the sensor's last ({MAX_PIXELS - 1}): "
                f"use {setting('first_pixel', MAX_PIXELS - pixels)} or lower")
    return None


#: Kinds that need neither the board's clock nor its other registers.
_OFFLINE = (WHOLE, CHOICE, PIXELS, PIXEL)


def check_offline(settings: Mapping[str, Any], *, style: str = "flag") -> None:
    """Refuse, before a board is opened, the settings that are wrong whatever the board: a
    value out of range, not a choice, ``--pixels`` not a power of two, or ``--pixels`` with
    ``--bin-shift`` (both given) that fit no board (judged against :data:`DEFAULT_BANK_BITS`, the
    largest bank). Raises :exc:`~fliss.host.errors.SettingsError`; what depends on the board is
    checked by :func:`convert`."""
    context = Context(DEFAULT_CLOCK_HZ, defaults(DEFAULT_CLOCK_HZ), style)
    given = {}
    for name, value in settings.items():
        option = BY_OPTION.get(name)
        if option is None or value is None or option.kind not in _OFFLINE:
            continue
        given.update(option.kind.convert(option, value, context))
    if "pixel_bits" in given and "bin_shift" in given:
        split = split_problem({**context.registers, **given}, DEFAULT_BANK_BITS, style)
        if split:
            raise SettingsError(split)


def _problems(registers, labels, clock_hz, bank_bits):
    # The gateware's consistency checks, naming settings as the caller does, with units.
    found = []
    if registers["gate_start"] > registers["gate_end"]:
        step_s = code_s(registers, clock_hz)
        found.append(f"{labels['gate_start']} ({format_time(registers['gate_start'] * step_s)}"
                     f", {registers['gate_start']} codes) must not be after "
                     f"{labels['gate_end']} ({format_time(registers['gate_end'] * step_s)}, "
                     f"{registers['gate_end']} codes)")
    names = "|".join(sorted(BY_NAME, key=len, reverse=True))

    def named(match):
        text = labels.get(match.group(1), match.group(1))
        if match.group(2):
            cycles = int(match.group(2))
            text += f" ({format_time(cycles / clock_hz)}, {cycles} cycles)"
        return text

    for message in problems(registers, bank_bits):
        if not message.startswith("gate_start "):
            found.append(re.sub(rf"(?<![*\w])({names})\b(?: \((\d+) cycles\))?", named,
                                message))
    return found


class Settings(Mapping):
    """A board's settings in units, read-only: a mapping from setting name to value
    (``"10 ms"``, ``"masked"``, ``6``), one per register, that :meth:`~fliss.host.board.Board.configure` takes
    back unchanged.

    Attributes
    ----------
    registers : dict
        The register values behind them.
    clock_hz : int
        The board's clock frequency.
    """

    def __init__(self, registers: Mapping[str, int], clock_hz: int) -> None:
        self.registers = dict(registers)
        self.clock_hz = int(clock_hz)
        self._values = {option.name: option.kind.show(option, self.registers, self.clock_hz)
                        for option in OPTIONS if option.shown}

    def __getitem__(self, name):
        return self._values[name]

    def __iter__(self):
        return iter(self._values)

    def __len__(self):
        return len(self._values)

    def __repr__(self):
        return "Settings(" + ", ".join(f"{name}={value!r}" for name, value in self.items()) + ")"

    @property
    def integration_s(self) -> float:
        """Integration time of each histogram (each raw block), in seconds."""
        return self.registers["integration"] / self.clock_hz

    @property
    def code_s(self) -> float:
        """Seconds per timestamp code."""
        return code_s(self.registers, self.clock_hz)

    @property
    def pixels(self) -> int:
        """Pixels of a frame."""
        return 1 << self.registers["pixel_bits"]

    @property
    def addresses(self) -> np.ndarray:
        """The pixel addresses of a frame, ``(pixels,)``."""
        return self.registers["first_pixel"] + np.arange(self.pixels)

    @property
    def bins(self) -> int:
        """Bins of a histogram (of each pixel's)."""
        return (1 << TIMESTAMP_BITS) >> self.registers["bin_shift"]

    @property
    def bin_s(self) -> float:
        """Width of a histogram bin, in seconds."""
        return (1 << self.registers["bin_shift"]) * self.code_s

    @property
    def time_s(self) -> np.ndarray:
        """Time of the centre of each histogram bin from the TDC start, in seconds."""
        return (np.arange(self.bins) + 0.5) * self.bin_s


def describe(registers: Mapping[str, int], clock_hz: int) -> Settings:
    """The :class:`Settings` in units of register values ``registers``."""
    return Settings(registers, clock_hz)

