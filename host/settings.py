"""Board settings with units: ``{"integration": "10ms", "mode": "masked"}`` as register values.

One table, :data:`OPTIONS`, says for each setting its name (a keyword of
:meth:`fliss.host.board.Board.configure`, and with ``--`` and dashes the flag of ``fliss config``
and ``fliss capture``), the register it sets and its :class:`Kind`: how a value with units
becomes a register value for a given clock, and back (the kinds: :mod:`fliss.host.setting_kinds`).
A new setting is one entry; one wider than a register (a key) is one entry whose kind returns
several registers.

The rules, the same in the library and on the command line:

* A time takes a unit: ``"10ms"``, ``"75 ns"``, or whole clock cycles, ``"800cycles"`` (gate
  times: TDC codes, ``"2000codes"``). A bare number is refused (``10`` could be cycles, seconds
  or milliseconds). A frequency takes a unit (``"1MHz"``) or is a number of hertz.
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
from ..hdl.registers import BY_NAME, AcquisitionMode, TdcSource, iv_problem, problems, value_of
from ..hdl.settings import DelayMode
from .errors import SettingsError
from .setting_kinds import (CHOICE, FREQUENCY, GATE, IV, KEY, TIME, WHOLE, Context, Kind,
                            code_s, exact_frequency, exact_time, said)
from .units import format_time, parse_time


__all__ = ["RoundingWarning", "Kind", "Option", "OPTIONS", "BY_OPTION", "Conversion",
           "Settings", "convert", "describe", "duration_s", "exact_time", "exact_frequency",
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


def _names(enum):
    return {member.name.lower(): member.value for member in enum}


_MODES = _names(DelayMode)
_ON_OFF = {"off": 0, "on": 1}

#: Every setting, in the order they are converted (``tdc`` before the gate, which depends on
#: it) and shown.
OPTIONS: Tuple[Option, ...] = (
    Option("readout", "acquisition", CHOICE, "what the board sends: histograms made on the "
           "board, or every event", choices=_names(AcquisitionMode)),
    Option("mode", "delay_mode", CHOICE, "victim delay source", choices=_MODES),
    Option("length", "length", WHOLE, "register length of the mseq source (bits)", "L"),
    Option("mask_width", "mask_width", WHOLE, "mask width of the masked source (bits)", "WM"),
    Option("seed", "seed", WHOLE, "non-zero seed of the victim delay source (0x for hex)", "S"),
    Option("prf", "period", FREQUENCY, "nominal pulse repetition frequency (1MHz): sets the "
           "period", "HZ"),
    Option("period_cycles", "period", WHOLE, "nominal laser period in clock cycles", "N",
           shown=False),
    Option("scheduler", "grid", CHOICE, "interval: pulses T + R apart; grid: pulse k at k T + R",
           choices={"interval": 0, "grid": 1}),
    Option("pulse_width", "pulse_width", TIME, "laser trigger pulse width (25ns)", "TIME"),
    Option("aggressor", "aggressor", CHOICE, "aggressor emitter", choices=_ON_OFF),
    Option("aggressor_prf", "aggressor_period", FREQUENCY, "aggressor pulse repetition "
           "frequency", "HZ"),
    Option("aggressor_period_cycles", "aggressor_period", WHOLE, "aggressor period in clock "
           "cycles", "N", shown=False),
    Option("aggressor_offset", "aggressor_offset", TIME, "aggressor offset after the victim "
           "(75ns)", "TIME"),
    Option("aggressor_width", "aggressor_width", TIME, "aggressor trigger pulse width", "TIME"),
    Option("aggressor_mode", "aggressor_delay_mode", CHOICE, "aggressor's own delay source",
           choices=_MODES),
    Option("aggressor_length", "aggressor_length", WHOLE, "aggressor mseq register length "
           "(bits)", "L"),
    Option("aggressor_mask_width", "aggressor_mask_width", WHOLE, "aggressor mask width (bits)",
           "WM"),
    Option("aggressor_seed", "aggressor_seed", WHOLE, "aggressor delay source seed", "S"),
    Option("tdc", "tdc_source", CHOICE, "event source: the sensor's timestamp bus or the "
           "built-in coarse TDC", choices=_names(TdcSource)),
    Option("gate_start", "gate_start", GATE, "first timestamp accepted (time from the TDC "
           "start: 100ns, or 2000codes)", "TIME"),
    Option("gate_end", "gate_end", GATE, "last timestamp accepted (100ns, or 2000codes)",
           "TIME"),
    Option("bin_shift", "bin_shift", WHOLE, "histogram bins are 2**N codes wide", "N"),
    Option("integration", "integration", TIME, "histogram integration time (10ms), and raw "
           "block length", "TIME"),
    Option("key", "key0", KEY, "key of the keyed source: 20 hex digits as the test vectors print "
           "it, or random (from the operating system's generator); write-only: the board never "
           "reads it back", "HEX|random", shown=False),
    Option("iv", "iv0", IV, "IV of the keyed source (20 hex digits); reads as the IV in use, "
           "and a new IV must be above it unless a new key is given too", "HEX"),
)

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


def convert(settings: Mapping[str, Any], clock_hz: int, current: Mapping[str, int], *,
            style: str = "keyword") -> Conversion:
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
    found = _problems(context.registers, labels, context.clock_hz)
    iv = iv_problem(changes, context.registers, value_of(current, "iv"))
    if iv:
        found.append(f"{BY_OPTION['iv'].label(style)}: {iv} (give a higher IV or a new key)")
    if found:
        raise SettingsError("; ".join(found))
    return Conversion(changes, context.registers, context.notes, written)


def _problems(registers, labels, clock_hz):
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

    for message in problems(registers):
        if not message.startswith("gate_start "):
            found.append(re.sub(rf"(?<![*\w])({names})\b(?: \((\d+) cycles\))?", named,
                                message))
    return found


class Settings(Mapping):
    """A board's settings in units, read-only: a mapping from setting name to value
    (``"10 ms"``, ``"masked"``, ``6``), one per register, that :meth:`Board.configure` takes
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
    def bins(self) -> int:
        """Bins of a histogram."""
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

