"""Register map of the FLISS top level: the one definition of every run-time setting.

Each register is 32 bits on the wire (``WRITE`` and ``READ`` packets, see
:mod:`fliss.hdl.protocol`) and holds ``width`` bits in the gateware. A write is refused (NAK
``OUT_OF_RANGE``, nothing applied) when the value is outside ``[minimum, maximum]`` or when the
settings it would make are inconsistent (:func:`problems`).

One table, :data:`ROWS`, says everything about each register (a :class:`Row`, see
:mod:`.register_rows`): its address, the struct field it feeds, its reset value and meaning, its
kind (time, frequency, whole number, choice, ...), choices and display, and the keywords and flags
that set it on the host with their help. Its width, limits and unit are those of its field:
registers come in groups (:class:`RegisterGroup`, :data:`GROUPS`) that travel together as one
struct to the block that uses them: the victim's and the aggressor's delay cores (both from one
definition, :data:`DELAY_SETTINGS`, whose layout is :class:`DelaySettings`), the aggressor
emitter's own settings, the event filter's gate, the histogram's frames, and the top level's
own choices (acquisition), the fine TDC's (fine_tdc), and the key and IV of the victim's keyed
delay source (keying). The link has no settings. The gateware (:mod:`.regfile`), the host's
settings, checks and ``fliss config`` (:mod:`fliss.host.settings`), the command model, the files
and ``docs/protocol.md`` all read this table: a new register is a row here (and a field of its
group's struct) and its use in its block.

A definitions module: it imports no gateware (the limits come from :mod:`.delay.settings`).
"""

from amaranth.hdl import Shape
from amaranth.lib import data, enum

from .clock import DEFAULT_PRF_HZ, MIN_PERIOD_CYCLES
from .event import ADDRESS_BITS, TIMESTAMP_BITS
from .protocol import AcquisitionMode
from .delay.modes import DelayMode, SIZES, core_modes, mode_maximum
from .finetdc import CODE_BITS as FINE_CODE_BITS, LSB_SELECTS as FINE_LSB_SELECTS, \
    TABLE_BITS as FINE_TABLE_BITS, HitInput
from .delay.settings import BANK_BITS, IV_BITS, KEY_BITS, PERIOD_WIDTH, PULSE_WIDTH_WIDTH
from .register_checks import (delay_group_problems, group_values, iv_problem, split_problems,
                              value_of, words_of)
from .register_rows import (CHOICE, FREQUENCY, GATE, IV, KEY, PIXEL, PIXELS, TIME, WHOLE, Hertz,
                            Keyword, Register, RegisterGroup, Row, Seconds, Setting, choices_of)


__all__ = ["AcquisitionMode", "TdcSource", "Register", "Setting", "RegisterGroup", "Row",
           "Keyword", "ROWS",
           "DELAY_SETTINGS", "KEYED_SOURCE", "VICTIM", "AGGRESSOR", "AGGRESSOR_DELAY", "ACQUISITION", "GATE",
           "HISTOGRAM", "DEPTH", "FINE_TDC", "KEYING", "GROUPS",
           "REGISTERS", "BY_NAME", "BY_ADDRESS", "RECORDED", "DelaySettings", "settings_layout",
           "register_maxima", "defaults", "group_values", "problems", "split_problems", "words_of",
           "value_of",
           "iv_problem"]


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


def _sized(name):
    # A setting that sizes a mode's delays (:data:`~.delay.modes.SIZES`), in bits
    size = SIZES[name]
    return Setting(name, size.maximum.bit_length(), size.minimum, size.maximum, "bits")


#: The settings of a delay core (:class:`~fliss.hdl.delay.core.DelayCore`): delay source, then
#: scheduler and laser trigger.
DELAY_SETTINGS = (
    Setting("mode",        Shape.cast(DelayMode).width, 0, _MODE_MAX),
    _sized("length"),
    _sized("mask_width"),
    Setting("seed",        32,                1,              _U32),
    Setting("period",      PERIOD_WIDTH,      MIN_PERIOD_CYCLES, _U32, "cycles"),
    Setting("grid",        1,                 0,              1),
    Setting("pulse_width", PULSE_WIDTH_WIDTH, 1,              (1 << PULSE_WIDTH_WIDTH) - 1,
            "cycles"),
)

#: The aggressor emitter's own settings (:class:`~fliss.hdl.delay.aggressor.Aggressor`).
AGGRESSOR_SETTINGS = (
    Setting("enable", 1,  0, 1),
    Setting("offset", 32, 0, _U32, "cycles"),
)

#: What is acquired, and from where (the top level's own choices).
ACQUISITION_SETTINGS = (
    Setting("mode",       2, 0, max(mode.value for mode in AcquisitionMode)),
    Setting("tdc_source", 2, 0, max(source.value for source in TdcSource)),
)

#: The fine TDC (:class:`~fliss.hdl.finetdc.tdc.FineTdc`): its timestamp LSB, its input, and
#: the host's way into its calibration table: a WRITE of ``table_address`` moves the table's
#: pointer there, each WRITE of ``table_data`` writes the entry at the pointer and moves it on
#: (in a WRITE of both, the pointer moves first: such a WRITE is safe to repeat), a READ of
#: ``table_data`` gives the entry at the pointer.
FINE_TDC_SETTINGS = (
    Setting("lsb",   2, 0, FINE_LSB_SELECTS - 1),
    Setting("input", Shape.cast(HitInput).width, 0, max(i.value for i in HitInput)),
    Setting("table_address", FINE_CODE_BITS, 0, (1 << FINE_CODE_BITS) - 1),
    Setting("table_data", FINE_TABLE_BITS, 0, (1 << FINE_TABLE_BITS) - 1),
)

#: The event filter's gate (:class:`~fliss.hdl.tdc.EventFilter`): the timestamps it accepts,
#: and whether it keeps the events the sensor flags as collisions.
GATE_SETTINGS = (
    Setting("start", TIMESTAMP_BITS, 0, (1 << TIMESTAMP_BITS) - 1, "codes"),
    Setting("end",   TIMESTAMP_BITS, 0, (1 << TIMESTAMP_BITS) - 1, "codes"),
    Setting("drop_collisions", 1, 0, 1),
)

#: The histogram's frames (:class:`~fliss.hdl.histogram.engine.Histogram`): bin width, integration
#: time, and how its bank is split between pixels. A frame holds ``2**pixel_bits`` pixels, the
#: addresses ``first_pixel …``, each of ``2**(13 - bin_shift)`` bins; the readout sends them
#: pixel after pixel (flat index ``pixel << (13 - bin_shift) | bin``).
HISTOGRAM_SETTINGS = (
    Setting("bin_shift",   4,  0, TIMESTAMP_BITS),
    Setting("integration", 32, 1, _U32, "cycles"),
    Setting("pixel_bits",  3,  0, ADDRESS_BITS),
    Setting("first_pixel", ADDRESS_BITS, 0, (1 << ADDRESS_BITS) - 1),
    Setting("full_readout", 1, 0, 1),
)

#: The depth engine (:class:`~fliss.hdl.depth.engine.DepthEngine`): matched filter and threshold.
DEPTH_SETTINGS = (
    Setting("filter",    5,  1, 16, "bins"),
    Setting("threshold", 16, 0, (1 << 16) - 1, "counts"),
)

#: Key and IV of the victim's ``keyed`` source (:class:`~fliss.hdl.delay.keyed.KeyedStream`): the
#: 80-bit integers their printed bytes spell (:mod:`fliss.sim.models.trivium`), in 32-bit words, least
#: significant first. The key is write-only. The IV reads as the IV in use (or, stopped, of the
#: next run); a WRITE of the IV that writes no key must put it above the IV in use, so that
#: under one key no IV (and so no keystream) is used twice. The IV registers come before the
#: key's, last in the map: a WRITE of a range of registers that ends below them (any other
#: setting, or the IV) never rewrites the key with what a READ gave.
KEYING_SETTINGS = (
    Setting("iv0",  32,           0, _U32),
    Setting("iv1",  32,           0, _U32),
    Setting("iv2",  IV_BITS - 64, 0, (1 << (IV_BITS - 64)) - 1),
    Setting("key0", 32,           0, _U32),
    Setting("key1", 32,           0, _U32),
    Setting("key2", KEY_BITS - 64, 0, (1 << (KEY_BITS - 64)) - 1),
)

#: Every register, in the order the host converts and shows its settings (the fine TDC's after
#: ``tdc_source``, before the gate that depends on them): address, struct field, reset value,
#: meaning, kind, keywords (with their help) and the rest (:class:`Row`).
ROWS = (
    Row("acquisition", 0x00, "acquisition.mode", AcquisitionMode.HISTOGRAM.value,
        "acquisition mode: 0 histogram, 1 raw events, 2 depth frames", CHOICE,
        (Keyword("readout", "what the board sends: histograms made on the board (image: the "
                 "same, saved per pixel), every event (raw), or depth frames"),),
        choices=choices_of(AcquisitionMode, image=AcquisitionMode.HISTOGRAM.value)),
    Row("delay_mode", 0x01, "victim.mode", DelayMode.MSEQ.value,
        f"victim delay source: {_modes_doc()}", CHOICE,
        (Keyword("mode", "victim delay source"),), choices=choices_of(DelayMode)),
    Row("length", 0x02, "victim.length", 6, "register length L of the mseq source", WHOLE,
        (Keyword("length", "register length of the mseq source (bits)", "L"),)),
    Row("mask_width", 0x03, "victim.mask_width", 6, "mask width Wm of the masked source", WHOLE,
        (Keyword("mask_width", "mask width of the masked source (bits)", "WM"),)),
    Row("seed", 0x04, "victim.seed", 1, "seed of the victim delay source (below 2**L for mseq)",
        WHOLE, (Keyword("seed", "non-zero seed of the victim delay source (0x for hex)", "S"),),
        display="{value:#x}"),
    Row("period", 0x05, "victim.period", Hertz(DEFAULT_PRF_HZ),
        "nominal laser period T ({default} PRF by default)", FREQUENCY,
        (Keyword("prf", "nominal pulse repetition frequency ({default}): sets the period", "HZ"),
         Keyword("period_cycles", "nominal laser period in clock cycles", "N", WHOLE,
                 shown=False))),
    Row("grid", 0x06, "victim.grid", 0,
        "scheduler mode: 0 interval (T + R apart), 1 grid (k T + R)", CHOICE,
        (Keyword("scheduler", "interval: pulses T + R apart; grid: pulse k at k T + R"),),
        choices={"interval": 0, "grid": 1}),
    Row("pulse_width", 0x07, "victim.pulse_width", 1,
        "laser trigger pulse width, shorter than the period", TIME,
        (Keyword("pulse_width", "laser trigger pulse width ({after_reset})", "TIME"),)),
    Row("aggressor", 0x08, "aggressor.enable", 0, "aggressor emitter: 0 off, 1 on", CHOICE,
        (Keyword("aggressor", "aggressor emitter"),), choices={"off": 0, "on": 1}),
    Row("aggressor_period", 0x09, "aggressor_delay.period", Hertz(DEFAULT_PRF_HZ),
        "aggressor period", FREQUENCY,
        (Keyword("aggressor_prf", "aggressor pulse repetition frequency", "HZ"),
         Keyword("aggressor_period_cycles", "aggressor period in clock cycles", "N", WHOLE,
                 shown=False))),
    Row("aggressor_offset", 0x0a, "aggressor.offset", Seconds(75e-9),
        "aggressor start offset after the victim's start ({default} by default)", TIME,
        (Keyword("aggressor_offset", "aggressor offset after the victim ({default})", "TIME"),)),
    Row("aggressor_width", 0x0b, "aggressor_delay.pulse_width", 1,
        "aggressor trigger pulse width, shorter than its period", TIME,
        (Keyword("aggressor_width", "aggressor trigger pulse width ({after_reset})", "TIME"),)),
    Row("aggressor_delay_mode", 0x0c, "aggressor_delay.mode", DelayMode.OFF.value,
        f"aggressor's own delay source: {_modes_doc(_AGGRESSOR_KEYED)} (not keyed)", CHOICE,
        (Keyword("aggressor_mode", "aggressor's own delay source"),),
        choices=choices_of(DelayMode)),
    Row("aggressor_length", 0x0d, "aggressor_delay.length", 6,
        "register length of the aggressor's mseq source", WHOLE,
        (Keyword("aggressor_length", "aggressor mseq register length (bits)", "L"),)),
    Row("aggressor_mask_width", 0x0e, "aggressor_delay.mask_width", 6,
        "mask width of the aggressor's masked source", WHOLE,
        (Keyword("aggressor_mask_width", "aggressor mask width (bits)", "WM"),)),
    Row("aggressor_seed", 0x0f, "aggressor_delay.seed", 0xACE1,
        "seed of the aggressor's delay source", WHOLE,
        (Keyword("aggressor_seed", "aggressor delay source seed", "S"),), display="{value:#x}"),
    Row("tdc_source", 0x10, "acquisition.tdc_source", TdcSource.SENSOR.value,
        "event source: 0 sensor timestamp bus, 1 built-in coarse TDC, 2 fine TDC, 3 fine TDC raw "
        "tap codes", CHOICE,
        (Keyword("tdc", "event source: the sensor's timestamp bus, the built-in coarse TDC, the "
                 "fine TDC (calibrated) or its raw tap codes"),), choices=choices_of(TdcSource)),
    Row("fine_lsb", 0x1b, "fine_tdc.lsb", 0,
        "fine TDC timestamp LSB: 50 ps / 2**fine_lsb (0 to 2)", CHOICE,
        (Keyword("fine_lsb", "fine TDC timestamp LSB (range 409.6, 204.8, 102.4 ns)"),),
        choices={"50ps": 0, "25ps": 1, "12.5ps": 2}),
    Row("tdc_input", 0x1c, "fine_tdc.input", 0,
        "fine TDC input: 0 photon pin, 1 on-chip oscillator, 2 laser output's pad read back, "
        "3 aggressor's trigger's pad read back", CHOICE,
        (Keyword("tdc_input", "fine TDC input: the photon pin, the on-chip oscillator "
                 "(calibration), or the laser's or the aggressor's output read back at its pad "
                 "(the self-test)"),), choices=choices_of(HitInput)),
    Row("table_address", 0x1d, "fine_tdc.table_address", 0,
        "fine TDC calibration table: a write moves the table's pointer here", WHOLE,
        (Keyword("table_address", "fine TDC calibration table: move its pointer to entry N",
                 "N"),)),
    Row("table_data", 0x1e, "fine_tdc.table_data", 0,
        "fine TDC calibration table: a write puts the entry (12.5 ps units) at the pointer (the "
        "one just written, in a write of both) and moves the pointer on; a read gives the entry "
        "at the pointer", WHOLE,
        (Keyword("table_data", "fine TDC calibration table: write N (12.5 ps units) at the "
                 "pointer and move it on", "N"),)),
    Row("gate_start", 0x11, "gate.start", 0, "first timestamp accepted", GATE,
        (Keyword("gate_start", "first timestamp accepted (time from the TDC start: 100ns, or "
                 "2000codes)", "TIME"),)),
    Row("gate_end", 0x12, "gate.end", (1 << TIMESTAMP_BITS) - 1, "last timestamp accepted", GATE,
        (Keyword("gate_end", "last timestamp accepted (100ns, or 2000codes)", "TIME"),)),
    Row("bin_shift", 0x13, "histogram.bin_shift", 0, "histogram bins are 2**bin_shift codes wide",
        WHOLE, (Keyword("bin_shift", "histogram bins are 2**N codes wide", "N"),),
        display="bin_width"),
    Row("integration", 0x14, "histogram.integration", Seconds(10e-3),
        "histogram integration time ({default} by default)", TIME,
        (Keyword("integration", "histogram integration time ({default}), and raw block length",
                 "TIME"),)),
    Row("collisions", 0x15, "gate.drop_collisions", 0,
        "events with the collision flag: 0 kept, 1 dropped (and counted)", CHOICE,
        (Keyword("collisions", "events the sensor flags as collisions: kept, or dropped and "
                 "counted"),),
        choices={"keep": 0, "drop": 1}, display={0: "keep", 1: "drop (counted)"}),
    Row("pixel_bits", 0x16, "histogram.pixel_bits", 0, "histograms of 2**pixel_bits pixels",
        PIXELS,
        (Keyword("pixels", f"pixels per frame, a power of two from 1 to {1 << ADDRESS_BITS} (the "
                 f"addresses --first-pixel ...); the bank holds 2**16 bins (2**14 on the "
                 f"iCEBreaker) shared among them", "N"),
         Keyword("pixel_bits", "frames of 2**N pixels", "N", WHOLE, shown=False))),
    Row("first_pixel", 0x17, "histogram.first_pixel", 0,
        "address of the first pixel histogrammed (others dropped, counted)", WHOLE,
        (Keyword("first_pixel", "address of the first pixel histogrammed", "ADDRESS"),
         Keyword("pixel", "the single-pixel bench: only the pixel at ADDRESS (--pixels 1 "
                 "--first-pixel ADDRESS)", "ADDRESS", PIXEL, shown=False)),
        display="pixel_range"),
    Row("full_readout", 0x18, "histogram.full_readout", 0,
        "histogram readout: 0 compact when shorter, 1 always full", CHOICE,
        (Keyword("histogram_format", "histogram readout: compact when shorter, or always "
                 "full"),), choices={"compact": 0, "full": 1}),
    Row("depth_filter", 0x19, "depth.filter", 4, "width of the depth engine's matched filter",
        WHOLE, (Keyword("depth_filter", "width of the depth engine's matched filter (bins)",
                        "N"),), display="filter_width"),
    Row("depth_threshold", 0x1a, "depth.threshold", 16,
        "least filtered peak height above background for a depth", WHOLE,
        (Keyword("depth_threshold", "least filtered peak height above background for a depth "
                 "(counts); a new pixel split (--pixels, --pixel, --bin-shift) sets the one that "
                 "suits it unless given, and it then follows the integration time, PRF and "
                 "filter: the height that background alone reaches in one of a hundred frames "
                 "of a pixel", "COUNTS"),), display="{value} counts"),
    Row("key0", 0x22, "keying.key0", 0, "key of the keyed source, bits 0-31 (write-only: reads 0)",
        KEY, (Keyword("key", "key of the keyed source: all 20 hex digits, as the test vectors "
                      "print it, or random (from the operating system's generator); write-only: "
                      "the board never reads it back", "HEX|random", shown=False),),
        write_only=True),
    Row("key1", 0x23, "keying.key1", 0, "key of the keyed source, bits 32-63 (write-only)", KEY,
        write_only=True),
    Row("key2", 0x24, "keying.key2", 0, "key of the keyed source, bits 64-79 (write-only)", KEY,
        write_only=True),
    Row("iv0", 0x1f, "keying.iv0", 0, "IV of the keyed source, bits 0-31 (reads: the IV in use)",
        IV, (Keyword("iv", "IV of the keyed source (up to 20 hex digits); reads as the IV in use, "
                     "and a new IV must be above it unless a new key is given too", "HEX"),),
        display="iv_in_use", in_use=True),
    Row("iv1", 0x20, "keying.iv1", 0, "IV of the keyed source, bits 32-63", IV, in_use=True),
    Row("iv2", 0x21, "keying.iv2", 0, "IV of the keyed source, bits 64-79", IV, in_use=True),
)

#: The victim's delay core.
VICTIM = RegisterGroup("victim", DELAY_SETTINGS, ROWS)

#: The aggressor's delay core: the victim's settings, without grid mode, and without the keyed
#: source (a second Trivium and key would cost as much again for an emulated aggressor, whose
#: delays need not be secret).
AGGRESSOR_DELAY = RegisterGroup("aggressor_delay", DELAY_SETTINGS, ROWS, fixed={"grid": 0},
                                limits={"mode": _AGGRESSOR_MODE_MAX})

AGGRESSOR = RegisterGroup("aggressor", AGGRESSOR_SETTINGS, ROWS)
ACQUISITION = RegisterGroup("acquisition", ACQUISITION_SETTINGS, ROWS)
FINE_TDC = RegisterGroup("fine_tdc", FINE_TDC_SETTINGS, ROWS)
GATE = RegisterGroup("gate", GATE_SETTINGS, ROWS)
HISTOGRAM = RegisterGroup("histogram", HISTOGRAM_SETTINGS, ROWS)
DEPTH = RegisterGroup("depth", DEPTH_SETTINGS, ROWS)
KEYING = RegisterGroup("keying", KEYING_SETTINGS, ROWS)

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
assert [row.name for row in ROWS] == [BY_NAME[row.name].name for row in ROWS]


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


def problems(values, bank_bits=BANK_BITS, keyed=True):
    """Inconsistencies between settings (each register already in range), as messages;
    ``bank_bits`` is the build's histogram bank (:func:`split_problems`), ``keyed`` whether it
    has the keyed source (:data:`KEYED_SOURCE`).

    The gateware refuses a write that would leave any of these.
    """
    found = []
    for group in GROUPS:
        if group.settings is DELAY_SETTINGS:
            found += delay_group_problems(group, values,
                                          keyed=keyed and KEYED_SOURCE[group.name])
    if values["gate_start"] > values["gate_end"]:
        found.append(f"gate_start ({values['gate_start']}) must not be after gate_end "
                     f"({values['gate_end']})")
    found += split_problems(values, bank_bits)
    return found
