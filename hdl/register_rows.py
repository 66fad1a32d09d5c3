"""What a row of the register map says (:mod:`fliss.hdl.registers` holds the rows).

A :class:`Row` is everything about one setting: its address, the field of the struct it feeds
(a :class:`RegisterGroup`'s :class:`Setting`, which gives its width, limits and unit), its reset
value, its meaning, its :data:`kind <KINDS>` (time, frequency, whole number, choice, ...), its
choices, how ``fliss config`` shows it, and the keywords (:class:`Keyword`: the names, help and
metavar of :meth:`fliss.host.board.Board.configure` and of the ``fliss config`` flags) that set it.
The gateware's register file, the host's settings and ``fliss config``, the model board, the
files and ``docs/protocol.md`` read the rows; nothing about a register is written elsewhere.

A definitions module: it imports no gateware.
"""

from dataclasses import dataclass, field
from typing import Mapping, Optional

from amaranth.lib import data

from .clock import period_cycles


__all__ = ["KINDS", "WHOLE", "CHOICE", "TIME", "FREQUENCY", "GATE", "KEY", "IV", "PIXELS", "PIXEL",
           "Seconds", "Hertz", "Keyword", "Row", "Register", "Setting", "RegisterGroup",
           "choices_of"]


#: The kinds of setting: how the host reads a value given with units and shows it
#: (:mod:`fliss.host.setting_kinds` maps each to its converter). ``whole``: a whole number;
#: ``choice``: one of the row's choices by name; ``time``: clock cycles, given as a time or
#: ``"800cycles"``; ``frequency``: a period in clock cycles, given as its frequency; ``gate``:
#: TDC codes, given as a time from the TDC start or ``"2000codes"``; ``key``, ``iv``: 80 bits in
#: three registers, given in hex; ``pixels``: ``pixel_bits`` given as a number of pixels;
#: ``pixel``: one pixel by its address (``pixel_bits`` 0 and ``first_pixel``).
KINDS = ("whole", "choice", "time", "frequency", "gate", "key", "iv", "pixels", "pixel")
WHOLE, CHOICE, TIME, FREQUENCY, GATE, KEY, IV, PIXELS, PIXEL = KINDS

_PREFIXES = ((1e9, "G"), (1e6, "M"), (1e3, "k"), (1, ""), (1e-3, "m"), (1e-6, "µ"), (1e-9, "n"),
             (1e-12, "p"))


def _si(value, unit):
    # "10 ms", "1 MHz": a quantity with the SI prefix that leaves 1 to 999 before the unit
    factor, prefix = next(((f, p) for f, p in _PREFIXES if abs(value) >= f), _PREFIXES[-1])
    return f"{value / factor:g} {prefix}{unit}"


@dataclass(frozen=True)
class Seconds:
    """A reset value given as a time: the nearest whole number of clock cycles at each clock.
    Its text (``"10 ms"``) is what the docs and the help say of the default."""
    seconds: float

    def __call__(self, clock_hz):
        return round(self.seconds * clock_hz)

    def __str__(self):
        return _si(self.seconds, "s")


@dataclass(frozen=True)
class Hertz:
    """A reset value given as a frequency: the period in whole clock cycles at each clock."""
    hz: float

    def __call__(self, clock_hz):
        return period_cycles(clock_hz, self.hz)

    def __str__(self):
        return _si(self.hz, "Hz")


def choices_of(enum, **more):
    """The choices of an enum's members, by their names in lower case (``{"off": 0, ...}``),
    with ``more`` names beside them."""
    return {**{member.name.lower(): member.value for member in enum}, **more}


@dataclass(frozen=True, eq=False)
class Keyword:
    """A name that sets a register: a keyword of :meth:`~fliss.host.board.Board.configure`,
    and with ``--`` and dashes the flag of ``fliss config`` and ``fliss capture``.

    ``kind`` and ``choices`` are the row's unless given (``period_cycles``, a whole number,
    beside ``prf``, a frequency). In ``help``, ``{default}`` stands for the row's reset quantity
    (``10ms``) and ``{after_reset}`` for its reset value in cycles and time at the default clock.
    ``shown`` is False for an alternative spelling of a register that another keyword shows:
    the host's settings have one value per register.
    """
    name: str
    help: str
    metavar: Optional[str] = None
    kind: Optional[str] = None
    choices: Optional[Mapping[str, int]] = None
    shown: bool = True


@dataclass(frozen=True, eq=False)
class Row:
    """One register as the map writes it (:data:`fliss.hdl.registers.ROWS`).

    ``at`` is ``"group.field"``: the field of a :class:`RegisterGroup`'s struct that the register
    holds (its width, limits and unit are the field's :class:`Setting`'s). ``reset`` is a number,
    a :class:`Seconds` or :class:`Hertz`, or a function of the clock frequency in Hz. In ``doc``,
    ``{default}`` stands for the reset quantity (``10 ms``). ``display`` says how ``fliss config``
    shows a value: None by its kind, a ``{value: text}`` table, or the name of a display of the
    host (:mod:`fliss.host.setting_display`). ``write_only``: a READ gives 0, and no file records
    it (the key). ``in_use``: a READ gives the value the board uses, which it may have moved on
    from the value written (the IV).
    """
    name: str
    address: int
    at: str
    reset: object
    doc: str
    kind: str = WHOLE
    keywords: tuple = ()
    choices: Optional[Mapping[str, int]] = None
    display: object = None
    write_only: bool = False
    in_use: bool = False

    def __post_init__(self):
        assert self.kind in KINDS, self
        assert all(k.kind is None or k.kind in KINDS for k in self.keywords), self
        assert (self.kind == CHOICE) == (self.choices is not None), self

    @property
    def group(self):
        return self.at.split(".")[0]

    @property
    def field(self):
        return self.at.split(".")[1]


@dataclass(frozen=True)
class Register:
    """One register: a :class:`Row` with its width in bits, allowed range and unit (those of
    its field's :class:`Setting`, the maximum lowered by its group's ``limits``)."""
    row: Row
    width: int
    minimum: int
    maximum: int
    unit: str

    # The row's facts, as the register's
    name = property(lambda self: self.row.name)
    address = property(lambda self: self.row.address)
    reset = property(lambda self: self.row.reset)
    kind = property(lambda self: self.row.kind)
    keywords = property(lambda self: self.row.keywords)
    choices = property(lambda self: self.row.choices)
    display = property(lambda self: self.row.display)
    write_only = property(lambda self: self.row.write_only)
    in_use = property(lambda self: self.row.in_use)
    group = property(lambda self: self.row.group)
    field = property(lambda self: self.row.field)

    @property
    def doc(self):
        """The meaning, with the reset quantity in it (``"... (10 ms by default)"``)."""
        return self.row.doc.replace("{default}", str(self.row.reset))

    def reset_value(self, clock_hz):
        return self.reset(clock_hz) if callable(self.reset) else self.reset

    def check(self, value):
        """Raise :exc:`ValueError` if ``value`` is out of this register's range."""
        if not isinstance(value, int) or not self.minimum <= value <= self.maximum:
            raise ValueError(f"Register {self.name} takes values from {self.minimum} to "
                             f"{self.maximum}{' ' + self.unit if self.unit else ''}, "
                             f"not {value!r}")


@dataclass(frozen=True)
class Setting:
    """One field of a settings struct: its name, width in bits, allowed range and unit (those of
    every register that holds it)."""
    name: str
    width: int
    minimum: int
    maximum: int
    unit: str = ""


@dataclass(frozen=True)
class RegisterGroup:
    """Registers that travel together as one struct (a block's ``settings`` port).

    ``settings`` are the struct's fields, in order; ``rows`` the map's rows, of which those
    ``at`` this group hold its fields. A field without a register (``fixed``: field -> value)
    reads as that constant. ``limits`` lowers the largest value of some fields' registers
    (field -> maximum). The register file exposes the group as one port of :meth:`layout`,
    named ``name``.
    """
    name: str
    settings: tuple
    rows: tuple = field(repr=False)
    fixed: dict = field(default_factory=dict)
    limits: dict = field(default_factory=dict)

    def __post_init__(self):
        names = {setting.name for setting in self.settings}
        held = [row.field for row in self.rows if row.group == self.name]
        assert len(held) == len(set(held)), self.name
        assert set(held) | set(self.fixed) == names, self.name
        assert not set(held) & set(self.fixed), self.name

    @property
    def members(self):
        """The group's registers, in field order."""
        rows = {row.field: row for row in self.rows if row.group == self.name}
        return tuple(
            Register(rows[s.name], s.width, s.minimum, self.limits.get(s.name, s.maximum), s.unit)
            for s in self.settings if s.name in rows)

    def register(self, field_name):
        """The register of field ``field_name``, or None for a fixed field."""
        return next((r for r in self.members if r.field == field_name), None)

    def layout(self, maxima=None):
        """``data.StructLayout`` of the group: each field as wide as its largest value needs,
        that of its register in ``maxima`` (register name -> largest value) if given there."""
        maxima = maxima or {}
        fields = {}
        for setting in self.settings:
            register = self.register(setting.name)
            top = setting.maximum if register is None else \
                maxima.get(register.name, register.maximum)
            fields[setting.name] = min(setting.width, top.bit_length())
        return data.StructLayout(fields)
