"""Register map of the FLISS top level: the one definition of every run-time setting.

Each register is 32 bits on the wire (``WRITE`` and ``READ`` packets, see
:mod:`fliss.hdl.protocol`) and holds ``width`` bits in the gateware. A write is refused (NAK
``OUT_OF_RANGE``, nothing applied) when the value is outside ``[minimum, maximum]`` or when the
settings it would make are inconsistent (:func:`problems`). The gateware (:mod:`.command`), the
host tool and ``docs/protocol.md`` all read this table.
"""

from dataclasses import dataclass

from amaranth.lib import data, enum

from . import DEFAULT_PRF_HZ, period_cycles
from .delay import DelayMode, MAX_MASK_WIDTH
from .event import TIMESTAMP_BITS
from .lfsr import MIN_LENGTH, MAX_LENGTH
from .scheduler import PERIOD_WIDTH, PULSE_WIDTH_WIDTH


__all__ = ["AcquisitionMode", "TdcSource", "Register", "REGISTERS", "BY_NAME", "BY_ADDRESS",
           "settings_layout", "defaults", "problems", "max_delay"]


class AcquisitionMode(enum.Enum, shape=1):
    """What the board sends while acquiring."""
    #: Histograms, one per integration time.
    HISTOGRAM = 0
    #: Every event, as EVENTS packets.
    RAW       = 1


class TdcSource(enum.Enum, shape=1):
    """Where events come from."""
    #: The sensor's timestamp bus (13-bit codes of 50 ps).
    SENSOR = 0
    #: The built-in coarse TDC on the photon-hit pin (codes of one clock cycle).
    COARSE = 1


@dataclass(frozen=True)
class Register:
    """One register: name, address, width in bits, allowed range, unit and meaning.

    ``reset`` is a number, or a function of the clock frequency in Hz.
    """
    name: str
    address: int
    width: int
    minimum: int
    maximum: int
    reset: object
    unit: str
    doc: str

    def reset_value(self, clock_hz):
        return self.reset(clock_hz) if callable(self.reset) else self.reset

    def check(self, value):
        """Raise :exc:`ValueError` if ``value`` is out of this register's range."""
        if not isinstance(value, int) or not self.minimum <= value <= self.maximum:
            raise ValueError(f"Register {self.name} takes values from {self.minimum} to "
                             f"{self.maximum}{' ' + self.unit if self.unit else ''}, "
                             f"not {value!r}")


def _period(clock_hz):
    return period_cycles(clock_hz, DEFAULT_PRF_HZ)


_U32 = (1 << 32) - 1
_MODE_MAX = max(mode.value for mode in DelayMode)

#: The registers, in address order.
REGISTERS = (
    Register("acquisition", 0x00, 1, 0, 1, AcquisitionMode.HISTOGRAM.value, "",
             "acquisition mode: 0 histogram, 1 raw events"),
    Register("delay_mode", 0x01, 2, 0, _MODE_MAX, DelayMode.MSEQ.value, "",
             "victim delay source: 0 off, 1 mseq, 2 masked"),
    Register("length", 0x02, 6, MIN_LENGTH, MAX_LENGTH, 6, "bits",
             "register length L of the mseq source"),
    Register("mask_width", 0x03, 5, 1, MAX_MASK_WIDTH, 6, "bits",
             "mask width Wm of the masked source"),
    Register("seed", 0x04, 32, 1, _U32, 1, "",
             "seed of the victim delay source (below 2**L for mseq)"),
    Register("period", 0x05, PERIOD_WIDTH, 2, _U32, _period, "cycles",
             "nominal laser period T (1 MHz PRF by default)"),
    Register("grid", 0x06, 1, 0, 1, 0, "",
             "scheduler mode: 0 interval (T + R apart), 1 grid (k T + R)"),
    Register("pulse_width", 0x07, PULSE_WIDTH_WIDTH, 1, (1 << PULSE_WIDTH_WIDTH) - 1, 1,
             "cycles", "laser trigger pulse width, shorter than the period"),
    Register("aggressor", 0x08, 1, 0, 1, 0, "", "aggressor emitter: 0 off, 1 on"),
    Register("aggressor_period", 0x09, PERIOD_WIDTH, 2, _U32, _period, "cycles",
             "aggressor period"),
    Register("aggressor_offset", 0x0a, 32, 0, _U32, lambda clock_hz: round(75e-9 * clock_hz),
             "cycles", "aggressor start offset after the victim's start (75 ns by default)"),
    Register("aggressor_width", 0x0b, PULSE_WIDTH_WIDTH, 1, (1 << PULSE_WIDTH_WIDTH) - 1, 1,
             "cycles", "aggressor trigger pulse width, shorter than its period"),
    Register("aggressor_delay_mode", 0x0c, 2, 0, _MODE_MAX, DelayMode.OFF.value, "",
             "aggressor's own delay source: 0 off, 1 mseq, 2 masked"),
    Register("aggressor_length", 0x0d, 6, MIN_LENGTH, MAX_LENGTH, 6, "bits",
             "register length of the aggressor's mseq source"),
    Register("aggressor_mask_width", 0x0e, 5, 1, MAX_MASK_WIDTH, 6, "bits",
             "mask width of the aggressor's masked source"),
    Register("aggressor_seed", 0x0f, 32, 1, _U32, 0xACE1, "",
             "seed of the aggressor's delay source"),
    Register("tdc_source", 0x10, 1, 0, 1, TdcSource.SENSOR.value, "",
             "event source: 0 sensor timestamp bus, 1 built-in coarse TDC"),
    Register("gate_start", 0x11, TIMESTAMP_BITS, 0, (1 << TIMESTAMP_BITS) - 1, 0, "codes",
             "first timestamp accepted"),
    Register("gate_end", 0x12, TIMESTAMP_BITS, 0, (1 << TIMESTAMP_BITS) - 1,
             (1 << TIMESTAMP_BITS) - 1, "codes", "last timestamp accepted"),
    Register("bin_shift", 0x13, 4, 0, TIMESTAMP_BITS, 0, "",
             "histogram bins are 2**bin_shift codes wide"),
    Register("integration", 0x14, 32, 1, _U32, lambda clock_hz: round(10e-3 * clock_hz),
             "cycles", "histogram integration time (10 ms by default)"),
)

BY_NAME = {register.name: register for register in REGISTERS}
BY_ADDRESS = {register.address: register for register in REGISTERS}

assert [register.address for register in REGISTERS] == list(range(len(REGISTERS)))


def settings_layout(maxima=None):
    """``data.StructLayout`` with one field per register, ``width`` bits each, or as many as
    its value in ``maxima`` (name -> largest value) needs when that is fewer."""
    maxima = maxima or {}
    return data.StructLayout({
        r.name: min(r.width, maxima.get(r.name, r.maximum).bit_length()) for r in REGISTERS})


def defaults(clock_hz):
    """Reset value of every register, by name."""
    return {register.name: register.reset_value(clock_hz) for register in REGISTERS}


def max_delay(mode, length, mask_width):
    """Largest delay of a delay source, in cycles (as the gateware computes it)."""
    if mode == DelayMode.MSEQ.value:
        return (1 << length) - 2
    if mode == DelayMode.MASKED.value:
        return (1 << mask_width) - 1
    return 0


def problems(values):
    """Inconsistencies between settings (each register already in range), as messages.

    The gateware refuses a write that would leave any of these.
    """
    v = values
    found = []
    if v["pulse_width"] >= v["period"]:
        found.append(f"pulse_width ({v['pulse_width']} cycles) must be shorter than period "
                     f"({v['period']} cycles)")
    if v["grid"] and max_delay(v["delay_mode"], v["length"], v["mask_width"]) + \
            v["pulse_width"] >= v["period"]:
        found.append("grid mode needs the largest delay plus pulse_width to be shorter than "
                     "period")
    if v["delay_mode"] == DelayMode.MSEQ.value and v["seed"] >> v["length"]:
        found.append(f"seed must be below 2**length = {1 << v['length']} for the mseq source")
    if v["aggressor_width"] >= v["aggressor_period"]:
        found.append(f"aggressor_width ({v['aggressor_width']} cycles) must be shorter than "
                     f"aggressor_period ({v['aggressor_period']} cycles)")
    if v["aggressor_delay_mode"] == DelayMode.MSEQ.value and \
            v["aggressor_seed"] >> v["aggressor_length"]:
        found.append(f"aggressor_seed must be below 2**aggressor_length = "
                     f"{1 << v['aggressor_length']} for the mseq source")
    if v["gate_start"] > v["gate_end"]:
        found.append(f"gate_start ({v['gate_start']}) must not be after gate_end "
                     f"({v['gate_end']})")
    return found
