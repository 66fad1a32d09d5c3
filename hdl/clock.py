"""The design's clock, and what its parameters come to in clock cycles: every conversion from a
clock frequency to cycles that the gateware, its models and the host share.

* :data:`DEFAULT_CLOCK_HZ`, :data:`DEFAULT_PRF_HZ`: the defaults of the paper;
* :func:`period_cycles`: the nominal laser period of a pulse repetition frequency;
* :func:`bit_cycles`: a UART bit, as a fixed-point number of cycles (:data:`FRACTION_BITS`);
* :func:`cycle_units`, :func:`elapsed_limit`: the clock period in the fine TDC's table units
  (:data:`~fliss.hdl.finetdc.UNIT_S`), and the cycles a fine timestamp can span.

Each refuses, with :exc:`ValueError`, a clock the gateware cannot be built for.
"""

import math

from .event import TIMESTAMP_BITS
from .finetdc import TABLE_BITS, UNIT_S


__all__ = ["DEFAULT_CLOCK_HZ", "DEFAULT_PRF_HZ", "MIN_PERIOD_CYCLES", "period_cycles",
           "FRACTION_BITS", "MIN_BIT_CYCLES", "BAUD_TOLERANCE", "bit_cycles",
           "cycle_units", "elapsed_limit"]


#: Default system clock of the design, in Hz (Table 1 of the paper).
DEFAULT_CLOCK_HZ = 80_000_000

#: Default nominal pulse repetition frequency, in Hz (Table 1 of the paper).
DEFAULT_PRF_HZ = 1_000_000

#: Shortest laser period, in clock cycles: the pulse scheduler takes a pulse every two cycles
#: at most.
MIN_PERIOD_CYCLES = 2


def period_cycles(clock_hz, prf_hz):
    """Nominal laser period ``T`` in clock cycles: ``round(clock_hz / prf_hz)``.

    Raises :exc:`ValueError` for a non-positive clock or PRF, or for a period shorter than
    :data:`MIN_PERIOD_CYCLES`.
    """
    if not clock_hz > 0:
        raise ValueError(f"Clock frequency must be positive, not {clock_hz!r}")
    if not prf_hz > 0:
        raise ValueError(f"Pulse repetition frequency must be positive, not {prf_hz!r}")
    period = round(clock_hz / prf_hz)
    if period < MIN_PERIOD_CYCLES:
        raise ValueError(f"Pulse repetition frequency {prf_hz} Hz is too high for a "
                         f"{clock_hz} Hz clock: the period must be at least "
                         f"{MIN_PERIOD_CYCLES} cycles")
    return period


# UART bit time -----------------------------------------------------------------------------------

#: Fraction bits of the UART's bit time.
FRACTION_BITS = 8

#: Shortest UART bit, in clock cycles: the receiver votes over three samples around the middle
#: of a bit and needs a cycle of margin on each side.
MIN_BIT_CYCLES = 4

#: Largest relative baud rate error accepted at construction.
BAUD_TOLERANCE = 0.02


def bit_cycles(clock_hz, baud):
    """UART bit time in clock cycles as a fixed-point integer with :data:`FRACTION_BITS`
    fraction bits.

    Raises :exc:`ValueError` for a non-positive clock or baud rate, and when the baud rate
    cannot be met within :data:`BAUD_TOLERANCE`: a bit must last at least
    :data:`MIN_BIT_CYCLES` cycles.
    """
    if not isinstance(clock_hz, (int, float)) or not clock_hz > 0:
        raise ValueError(f"Clock frequency must be positive, not {clock_hz!r}")
    if not isinstance(baud, (int, float)) or not baud > 0:
        raise ValueError(f"Baud rate must be positive, not {baud!r}")
    cycles = max(round(clock_hz * (1 << FRACTION_BITS) / baud), MIN_BIT_CYCLES << FRACTION_BITS)
    actual = clock_hz * (1 << FRACTION_BITS) / cycles
    error = actual / baud - 1
    if abs(error) > BAUD_TOLERANCE:
        raise ValueError(f"Baud rate {baud} cannot be met within 2% from a {clock_hz} Hz clock: "
                         f"the closest is {actual:.0f} baud ({error:+.1%}), as a bit lasts at "
                         f"least {MIN_BIT_CYCLES} cycles")
    return cycles


# Fine TDC ----------------------------------------------------------------------------------------

def cycle_units(clock_hz):
    """The clock period in the fine TDC's table units (:data:`~fliss.hdl.finetdc.UNIT_S`);
    refused unless whole."""
    units = 1 / (clock_hz * UNIT_S) if clock_hz > 0 else 0
    if not clock_hz > 0 or abs(units - round(units)) > 1e-6:
        raise ValueError(f"The fine TDC needs a clock period that is a whole multiple of "
                         f"{UNIT_S * 1e12:g} ps, not {clock_hz!r} Hz")
    return round(units)


def elapsed_limit(clock_hz):
    """Largest count of whole cycles since the TDC start that can still give a fine timestamp
    of 13 bits at the coarsest LSB (a later hit overflows)."""
    units = cycle_units(clock_hz)
    return math.ceil(((1 << TIMESTAMP_BITS) * 4 + (1 << TABLE_BITS)) / units) + 1
