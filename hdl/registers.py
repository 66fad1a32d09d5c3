"""Register map of the FLISS top level: the one definition of every run-time setting.

Each register is 32 bits on the wire (``WRITE`` and ``READ`` packets, see
:mod:`fliss.hdl.protocol`) and holds ``width`` bits in the gateware. A write is refused (NAK
``OUT_OF_RANGE``, nothing applied) when the value is outside ``[minimum, maximum]`` or when the
settings it would make are inconsistent (:func:`problems`). The gateware (:mod:`.regfile`), the
host tool and ``docs/protocol.md`` all read this table.

Registers come in groups (:class:`RegisterGroup`, :data:`GROUPS`) that travel together as one
struct to the block that uses them: the victim's and the aggressor's delay cores (both from one
definition, :data:`DELAY_SETTINGS`, whose layout is :class:`DelaySettings`), the aggressor
emitter's own settings, the event filter's gate, the histogram's frames, and the top level's
own choices (acquisition), the fine TDC's (fine_tdc), and the key and IV of the victim's keyed delay source (keying).
The link has no settings. A new field of a group is
added here and used in its block; the register file, its checks and the top level follow.

A definitions module: it imports no gateware (the limits come from :mod:`.delay.settings`).
"""

from dataclasses import dataclass, field

from amaranth.hdl import Shape
from amaranth.lib import data, enum

from .clock import DEFAULT_PRF_HZ, MIN_PERIOD_CYCLES, period_cycles
from .event import ADDRESS_BITS, TIMESTAMP_BITS
from .delay.modes import DelayMode, core_modes, delay_problems, mode_maximum
from .finetdc import CODE_BITS as FINE_CODE_BITS, LSB_SELECTS as FINE_LSB_SELECTS, \
    TABLE_BITS as FINE_TABLE_BITS, HitInput
from .delay.settings import (BANK_BITS, IV_BITS, KEY_BITS, MIN_LENGTH, MAX_LENGTH,
                             MAX_MASK_WIDTH, PERIOD_WIDTH, PULSE_WIDTH_WIDTH)


__all__ = ["AcquisitionMode", "TdcSource", "Register", "Setting", "RegisterGroup",
           "DELAY_SETTINGS", "KEYED_SOURCE", "VICTIM", "AGGRESSOR", "AGGRESSOR_DELAY",
           "ACQUISITION", "GATE", "HISTOGRAM", "DEPTH", "FINE_TDC", "KEYING", "GROUPS",
           "REGISTERS", "BY_NAME", "BY_ADDRESS", "RECORDED", "DelaySettings", "settings_layout",
           "register_maxima", "defaults", "group_values", "problems", "split_problems", "words_of",
           "value_of",
           "iv_problem"]


class AcquisitionMode(enum.Enum, shape=2):
    """What the board sends while acquiring."""
    #: Histograms, one per integration time (per pixel: see ``pixel_bits``).
    HISTOGRAM = 0
    #: Every event, as EVENTS packets.
    RAW       = 1
    #: Depth frames: per pixel, the position, height and background of its strongest peak,
    #: one DEPTH packet per integration time.
    DEPTH     = 2


class TdcSource(enum.Enum, shape=2):
    """Where events come from."""
    #: The sensor's timestamp bus (13-bit codes of 50 ps).
    SENSOR = 0
    #: The built-in coarse TDC on the photon-hit pin (codes of one clock cycle).
    COARSE = 1
    #: The fine TDC in the fabric (:mod:`fliss.hdl.finetdc`), calibrated: codes of
    #: ``50 ps / 2**fine_lsb``.
    FINE = 2
    #: The fine TDC's raw tap codes, for its code-density calibration.
    FINE_RAW = 3


@dataclass(frozen=True)
class Register:
    """One register: name, address, width in bits, allowed range, unit and meaning.

    ``reset`` is a number, or a function of the clock frequency in Hz. ``group`` and ``field``
    place it in a :class:`RegisterGroup`: the register is field ``field`` of the group's struct.
    ``write_only``: a READ gives 0, and no file records it (the key). ``in_use``: a READ gives
    the value the board uses, which it may have moved on from the value written (the IV).
    """
    name: str
    address: int
    width: int
    minimum: int
    maximum: int
    reset: object
    unit: str
    doc: str
    group: str = ""
    field: str = ""
    write_only: bool = False
    in_use: bool = False

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

    ``settings`` are the struct's fields, in order; ``registers`` gives the register that holds
    each field as ``field -> (name, address, reset, doc)``. A field without a register
    (``fixed``: field -> value) reads as that constant. ``limits`` lowers the largest value of
    some fields' registers (field -> maximum); ``write_only`` and ``in_use`` name fields whose
    registers are so (:class:`Register`). The register file exposes the group as one port of
    :meth:`layout`, named ``name``.
    """
    name: str
    settings: tuple
    registers: dict
    fixed: dict = field(default_factory=dict)
    limits: dict = field(default_factory=dict)
    write_only: frozenset = frozenset()
    in_use: frozenset = frozenset()

    def __post_init__(self):
        names = {setting.name for setting in self.settings}
        assert set(self.registers) | set(self.fixed) == names, self.name
        assert not set(self.registers) & set(self.fixed), self.name

    @property
    def members(self):
        """The group's registers, in field order."""
        return tuple(
            Register(name, address, setting.width, setting.minimum,
                     self.limits.get(setting.name, setting.maximum), reset, setting.unit, doc,
                     self.name, setting.name, setting.name in self.write_only,
                     setting.name in self.in_use)
            for setting in self.settings if setting.name in self.registers
            for name, address, reset, doc in [self.registers[setting.name]])

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


def _period(clock_hz):
    return period_cycles(clock_hz, DEFAULT_PRF_HZ)


_U32 = (1 << 32) - 1
_MODE_MAX = mode_maximum()

#: The delay cores' groups, by name, with whether their core may have the keyed source (the
#: victim's, in a build with it); the aggressor's has none (see :data:`AGGRESSOR_DELAY`).
KEYED_SOURCE = {"victim": True, "aggressor_delay": False}

#: The aggressor's delay modes: its largest, and their list for the register's doc.
_AGGRESSOR_KEYED = KEYED_SOURCE["aggressor_delay"]
_AGGRESSOR_MODE_MAX = mode_maximum(_AGGRESSOR_KEYED)


def _modes_doc(keyed=True):
    # "0 off, 1 mseq, …": the delay modes of a core (with the keyed source or without)
    return ", ".join(f"{row.mode.value} {row.name}" for row in core_modes(keyed))

#: The settings of a delay core (:class:`~fliss.hdl.delay.core.DelayCore`): delay source, then
#: scheduler and laser trigger.
DELAY_SETTINGS = (
    Setting("mode",        Shape.cast(DelayMode).width, 0, _MODE_MAX),
    Setting("length",      6,                 MIN_LENGTH,     MAX_LENGTH, "bits"),
    Setting("mask_width",  5,                 1,              MAX_MASK_WIDTH, "bits"),
    Setting("seed",        32,                1,              _U32),
    Setting("period",      PERIOD_WIDTH,      MIN_PERIOD_CYCLES, _U32, "cycles"),
    Setting("grid",        1,                 0,              1),
    Setting("pulse_width", PULSE_WIDTH_WIDTH, 1,              (1 << PULSE_WIDTH_WIDTH) - 1,
            "cycles"),
)

#: The victim's delay core.
VICTIM = RegisterGroup("victim", DELAY_SETTINGS, {
    "mode":        ("delay_mode", 0x01, DelayMode.MSEQ.value,
                    f"victim delay source: {_modes_doc()}"),
    "length":      ("length", 0x02, 6, "register length L of the mseq source"),
    "mask_width":  ("mask_width", 0x03, 6, "mask width Wm of the masked source"),
    "seed":        ("seed", 0x04, 1, "seed of the victim delay source (below 2**L for mseq)"),
    "period":      ("period", 0x05, _period, "nominal laser period T (1 MHz PRF by default)"),
    "grid":        ("grid", 0x06, 0,
                    "scheduler mode: 0 interval (T + R apart), 1 grid (k T + R)"),
    "pulse_width": ("pulse_width", 0x07, 1, "laser trigger pulse width, shorter than the period"),
})

#: The aggressor's delay core: the victim's settings, without grid mode, and without the keyed
#: source (a second Trivium and key would cost as much again for an emulated aggressor, whose
#: delays need not be secret).
AGGRESSOR_DELAY = RegisterGroup("aggressor_delay", DELAY_SETTINGS, {
    "period":      ("aggressor_period", 0x09, _period, "aggressor period"),
    "pulse_width": ("aggressor_width", 0x0b, 1,
                    "aggressor trigger pulse width, shorter than its period"),
    "mode":        ("aggressor_delay_mode", 0x0c, DelayMode.OFF.value,
                    f"aggressor's own delay source: {_modes_doc(_AGGRESSOR_KEYED)} "
                    f"(not keyed)"),
    "length":      ("aggressor_length", 0x0d, 6, "register length of the aggressor's mseq source"),
    "mask_width":  ("aggressor_mask_width", 0x0e, 6,
                    "mask width of the aggressor's masked source"),
    "seed":        ("aggressor_seed", 0x0f, 0xACE1, "seed of the aggressor's delay source"),
}, fixed={"grid": 0}, limits={"mode": _AGGRESSOR_MODE_MAX})

#: The aggressor emitter's own settings (:class:`~fliss.hdl.delay.aggressor.Aggressor`).
AGGRESSOR = RegisterGroup("aggressor", (
    Setting("enable", 1,  0, 1),
    Setting("offset", 32, 0, _U32, "cycles"),
), {
    "enable": ("aggressor", 0x08, 0, "aggressor emitter: 0 off, 1 on"),
    "offset": ("aggressor_offset", 0x0a, lambda clock_hz: round(75e-9 * clock_hz),
               "aggressor start offset after the victim's start (75 ns by default)"),
})

#: What is acquired, and from where (the top level's own choices).
ACQUISITION = RegisterGroup("acquisition", (
    Setting("mode",       2, 0, max(mode.value for mode in AcquisitionMode)),
    Setting("tdc_source", 2, 0, max(source.value for source in TdcSource)),
), {
    "mode":       ("acquisition", 0x00, 0, "acquisition mode: 0 histogram, 1 raw events, 2 depth frames"),
    "tdc_source": ("tdc_source", 0x10, 0,
                   "event source: 0 sensor timestamp bus, 1 built-in coarse TDC, 2 fine TDC, "
                   "3 fine TDC raw tap codes"),
})

#: The fine TDC (:class:`~fliss.hdl.finetdc.tdc.FineTdc`): its timestamp LSB, its input, and
#: the host's way into its calibration table: a WRITE of ``table_address`` moves the table's
#: pointer there, each WRITE of ``table_data`` writes the entry at the pointer and moves it on
#: (in a WRITE of both, the pointer moves first: such a WRITE is safe to repeat), a READ of
#: ``table_data`` gives the entry at the pointer.
FINE_TDC = RegisterGroup("fine_tdc", (
    Setting("lsb",   2, 0, FINE_LSB_SELECTS - 1),
    Setting("input", Shape.cast(HitInput).width, 0, max(i.value for i in HitInput)),
    Setting("table_address", FINE_CODE_BITS, 0, (1 << FINE_CODE_BITS) - 1),
    Setting("table_data", FINE_TABLE_BITS, 0, (1 << FINE_TABLE_BITS) - 1),
), {
    "lsb":   ("fine_lsb", 0x1b, 0, "fine TDC timestamp LSB: 50 ps / 2**fine_lsb (0 to 2)"),
    "input": ("tdc_input", 0x1c, 0,
              "fine TDC input: 0 photon pin, 1 on-chip oscillator, 2 laser output's pad read "
              "back, 3 aggressor's trigger's pad read back"),
    "table_address": ("table_address", 0x1d, 0,
                      "fine TDC calibration table: a write moves the table's pointer here"),
    "table_data": ("table_data", 0x1e, 0,
                   "fine TDC calibration table: a write puts the entry (12.5 ps units) at the "
                   "pointer (the one just written, in a write of both) and moves the pointer on; "
                   "a read gives the entry at the pointer"),
})

#: The event filter's gate (:class:`~fliss.hdl.tdc.EventFilter`): the timestamps it accepts,
#: and whether it keeps the events the sensor flags as collisions.
GATE = RegisterGroup("gate", (
    Setting("start", TIMESTAMP_BITS, 0, (1 << TIMESTAMP_BITS) - 1, "codes"),
    Setting("end",   TIMESTAMP_BITS, 0, (1 << TIMESTAMP_BITS) - 1, "codes"),
    Setting("drop_collisions", 1, 0, 1),
), {
    "start": ("gate_start", 0x11, 0, "first timestamp accepted"),
    "end":   ("gate_end", 0x12, (1 << TIMESTAMP_BITS) - 1, "last timestamp accepted"),
    "drop_collisions": ("collisions", 0x15, 0,
                        "events with the collision flag: 0 kept, 1 dropped (and counted)"),
})

#: The histogram's frames (:class:`~fliss.hdl.histogram.engine.Histogram`): bin width, integration
#: time, and how its bank is split between pixels. A frame holds ``2**pixel_bits`` pixels, the
#: addresses ``first_pixel …``, each of ``2**(13 - bin_shift)`` bins; the readout sends them
#: pixel after pixel (flat index ``pixel << (13 - bin_shift) | bin``).
HISTOGRAM = RegisterGroup("histogram", (
    Setting("bin_shift",   4,  0, TIMESTAMP_BITS),
    Setting("integration", 32, 1, _U32, "cycles"),
    Setting("pixel_bits",  3,  0, ADDRESS_BITS),
    Setting("first_pixel", ADDRESS_BITS, 0, (1 << ADDRESS_BITS) - 1),
    Setting("full_readout", 1, 0, 1),
), {
    "bin_shift":   ("bin_shift", 0x13, 0, "histogram bins are 2**bin_shift codes wide"),
    "integration": ("integration", 0x14, lambda clock_hz: round(10e-3 * clock_hz),
                    "histogram integration time (10 ms by default)"),
    "pixel_bits":  ("pixel_bits", 0x16, 0, "histograms of 2**pixel_bits pixels"),
    "first_pixel": ("first_pixel", 0x17, 0,
                    "address of the first pixel histogrammed (others dropped, counted)"),
    "full_readout": ("full_readout", 0x18, 0,
                     "histogram readout: 0 compact when shorter, 1 always full"),
})

#: The depth engine (:class:`~fliss.hdl.depth.engine.DepthEngine`): matched filter and threshold.
DEPTH = RegisterGroup("depth", (
    Setting("filter",    5,  1, 16, "bins"),
    Setting("threshold", 16, 0, (1 << 16) - 1, "counts"),
), {
    "filter":    ("depth_filter", 0x19, 4, "width of the depth engine's matched filter"),
    "threshold": ("depth_threshold", 0x1a, 16,
                  "least filtered peak height above background for a depth"),
})

#: Key and IV of the victim's ``keyed`` source (:class:`~fliss.hdl.delay.keyed.KeyedStream`): the
#: 80-bit integers their printed bytes spell (:mod:`fliss.sim.models.trivium`), in 32-bit words, least
#: significant first. The key is write-only. The IV reads as the IV in use (or, stopped, of the
#: next run); a WRITE of the IV that writes no key must put it above the IV in use, so that
#: under one key no IV (and so no keystream) is used twice. The IV registers come before the
#: key's, last in the map: a WRITE of a range of registers that ends below them (any other
#: setting, or the IV) never rewrites the key with what a READ gave.
KEYING = RegisterGroup("keying", (
    Setting("iv0",  32,           0, _U32),
    Setting("iv1",  32,           0, _U32),
    Setting("iv2",  IV_BITS - 64, 0, (1 << (IV_BITS - 64)) - 1),
    Setting("key0", 32,           0, _U32),
    Setting("key1", 32,           0, _U32),
    Setting("key2", KEY_BITS - 64, 0, (1 << (KEY_BITS - 64)) - 1),
), {
    "iv0":  ("iv0", 0x1f, 0, "IV of the keyed source, bits 0-31 (reads: the IV in use)"),
    "iv1":  ("iv1", 0x20, 0, "IV of the keyed source, bits 32-63"),
    "iv2":  ("iv2", 0x21, 0, "IV of the keyed source, bits 64-79"),
    "key0": ("key0", 0x22, 0, "key of the keyed source, bits 0-31 (write-only: reads 0)"),
    "key1": ("key1", 0x23, 0, "key of the keyed source, bits 32-63 (write-only)"),
    "key2": ("key2", 0x24, 0, "key of the keyed source, bits 64-79 (write-only)"),
}, write_only=frozenset({"key0", "key1", "key2"}), in_use=frozenset({"iv0", "iv1", "iv2"}))

#: Every group; the link has no settings, so it has no group.
GROUPS = (VICTIM, AGGRESSOR, AGGRESSOR_DELAY, ACQUISITION, GATE, HISTOGRAM, DEPTH, FINE_TDC,
          KEYING)

#: The registers, in address order.
REGISTERS = tuple(sorted((r for group in GROUPS for r in group.members),
                         key=lambda r: r.address))

BY_NAME = {register.name: register for register in REGISTERS}
BY_ADDRESS = {register.address: register for register in REGISTERS}

#: The registers a file records: all but the write-only ones (the key).
RECORDED = tuple(register for register in REGISTERS if not register.write_only)

assert [register.address for register in REGISTERS] == list(range(len(REGISTERS)))
assert AcquisitionMode.HISTOGRAM.value == BY_NAME["acquisition"].reset
assert TdcSource.SENSOR.value == BY_NAME["tdc_source"].reset


class DelaySettings(data.StructLayout):
    """Layout of a delay core's settings (:data:`DELAY_SETTINGS`): ``mode``, ``length``,
    ``mask_width``, ``seed``, ``period``, ``grid``, ``pulse_width``, each as wide as its largest
    value. It equals the layout of the register file's :data:`VICTIM` and
    :data:`AGGRESSOR_DELAY` ports for the same widths.

    Parameters
    ----------
    period_width, pulse_width_width : int
        Widths of ``period`` and ``pulse_width``, in bits.
    delays : bool
        Without delays, ``mode`` is zero bits wide (always ``OFF``).
    """

    def __init__(self, *, period_width=PERIOD_WIDTH, pulse_width_width=PULSE_WIDTH_WIDTH,
                 delays=True):
        tops = {"period": (1 << period_width) - 1, "pulse_width": (1 << pulse_width_width) - 1,
                "mode": _MODE_MAX if delays else DelayMode.OFF.value}
        widths = {setting.name: min(setting.width,
                                    tops.get(setting.name, setting.maximum).bit_length())
                  for setting in DELAY_SETTINGS}
        super().__init__({**widths, "mode": DelayMode if delays else 0})


def settings_layout(maxima=None):
    """``data.StructLayout`` with one field per register, ``width`` bits each, or as many as
    its value in ``maxima`` (name -> largest value) needs when that is fewer."""
    maxima = maxima or {}
    return data.StructLayout({
        r.name: min(r.width, maxima.get(r.name, r.maximum).bit_length()) for r in REGISTERS})


def register_maxima(maxima, clock_hz):
    """Largest value of every register, by name: the register map's, lowered by ``maxima``
    (name -> maximum). Refuses unknown names, and maxima that are not lower or would refuse
    the register's reset value."""
    result = {register.name: register.maximum for register in REGISTERS}
    if maxima is None:
        return result
    if not isinstance(maxima, dict):
        raise TypeError(f"Register maxima must be a dict of name -> maximum, not {maxima!r}")
    for name, maximum in maxima.items():
        if name not in BY_NAME:
            raise ValueError(f"Unknown register {name!r} in the register maxima")
        register = BY_NAME[name]
        if (not isinstance(maximum, int) or
                not max(register.minimum, register.reset_value(clock_hz)) <= maximum
                <= register.maximum):
            raise ValueError(f"Maximum of register {name} must be an integer from its reset "
                             f"value or minimum to {register.maximum}, not {maximum!r}")
        result[name] = maximum
    return result


def defaults(clock_hz):
    """Reset value of every register, by name."""
    return {register.name: register.reset_value(clock_hz) for register in REGISTERS}


def words_of(value, prefix):
    """The registers (``prefix`` 0, 1, 2: ``"key"`` or ``"iv"``) of an 80-bit key or IV."""
    return {f"{prefix}{k}": (value >> (32 * k)) & _U32 for k in range(3)}


def value_of(values, prefix):
    """The 80-bit key or IV of its registers (``prefix`` ``"key"`` or ``"iv"``) in ``values``."""
    return sum(values[f"{prefix}{k}"] << (32 * k) for k in range(3))


def iv_problem(written, values, iv_in_use):
    """The IV rule, as a message or None: a WRITE of the registers named in ``written`` that
    writes the IV (to ``values``) and no key must put the IV above ``iv_in_use``."""
    writes = set(written)
    if not writes & {"iv0", "iv1", "iv2"} or writes & {"key0", "key1", "key2"}:
        return None
    iv = value_of(values, "iv")
    if iv > iv_in_use:
        return None
    return (f"the IV ({iv:#022x}) must be above the IV in use ({iv_in_use:#022x}) unless a "
            f"new key is written with it: under one key no IV is used twice")


def group_values(group, values):
    """The fields of ``group`` from ``values`` (register name -> value), fixed ones included."""
    return {**group.fixed, **{r.field: values[r.name] for r in group.members}}


def _delay_problems(group, values, keyed):
    # The checks of one delay core's settings together (each register is checked on its own)
    return delay_problems(group_values(group, values),
                          names={r.field: r.name for r in group.members}, ranges=False,
                          keyed=keyed and KEYED_SOURCE[group.name])


def split_problems(values, bank_bits=BANK_BITS):
    """The histogram's pixel split against a bank of ``2**bank_bits`` bins (the build's,
    :attr:`~fliss.hdl.protocol.Identity` ``bank_bits``), as messages: ``2**pixel_bits`` pixels of
    ``2**(13 - bin_shift)`` bins must fit the bank, and the pixels ``first_pixel …
    first_pixel + 2**pixel_bits - 1`` must be addresses of the sensor (below 64)."""
    pixel_bits, shift, first = values["pixel_bits"], values["bin_shift"], values["first_pixel"]
    bin_bits = TIMESTAMP_BITS - shift
    found = []
    if pixel_bits + bin_bits > bank_bits:
        found.append(f"pixel_bits ({pixel_bits}) and bin_shift ({shift}) ask for "
                     f"{1 << pixel_bits} pixels of {1 << bin_bits} bins, more than this "
                     f"board's histogram bank holds ({1 << bank_bits} bins, bank_bits "
                     f"{bank_bits}): pixel_bits + 13 - bin_shift must be at most {bank_bits}")
    pixels = 1 << ADDRESS_BITS
    if first + (1 << pixel_bits) > pixels:
        found.append(f"first_pixel ({first}) plus {1 << pixel_bits} pixels (pixel_bits "
                     f"{pixel_bits}) goes past the last pixel address ({pixels - 1}): "
                     f"first_pixel + 2**pixel_bits must be at most {pixels}")
    return found


def problems(values, bank_bits=BANK_BITS, keyed=True):
    """Inconsistencies between settings (each register already in range), as messages;
    ``bank_bits`` is the build's histogram bank (:func:`split_problems`), ``keyed`` whether it
    has the keyed source (:data:`KEYED_SOURCE`).

    The gateware refuses a write that would leave any of these.
    """
    found = []
    for group in GROUPS:
        if group.settings is DELAY_SETTINGS:
            found += _delay_problems(group, values, keyed)
    if values["gate_start"] > values["gate_end"]:
        found.append(f"gate_start ({values['gate_start']}) must not be after gate_end "
                     f"({values['gate_end']})")
    found += split_problems(values, bank_bits)
    return found
