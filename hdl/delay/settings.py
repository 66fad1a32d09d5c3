"""Limits of the delay core's settings: the numbers the register map, the gateware and the models
share.

A definitions module: it imports no gateware, so :mod:`.registers` can build the register map
from it and the blocks (:mod:`.lfsr`, :mod:`.delay`, :mod:`.scheduler`) can import it.
"""

from fractions import Fraction

from amaranth.lib import enum


__all__ = ["MIN_LENGTH", "MAX_LENGTH", "MAX_MASK_WIDTH", "MASKED_LENGTH", "MASKED_STEPS",
           "KEY_BITS", "IV_BITS", "KEYED_ROUNDS", "KEYED_INIT_CYCLES", "KEYED_START_CYCLES",
           "DELAY_WIDTH", "PERIOD_WIDTH",
           "PULSE_WIDTH_WIDTH", "BANK_BITS", "MIN_BANK_BITS", "MAX_BANK_BITS", "DelayMode",
           "check_widths", "mean_delay"]


#: Shortest and longest supported register of the m-sequence source, in bits.
MIN_LENGTH = 2
MAX_LENGTH = 32

#: Widest bit-mask of the ``masked`` source, in bits.
MAX_MASK_WIDTH = 16

#: Length of the register behind the ``masked`` source, in bits.
MASKED_LENGTH = 32

#: Register steps per pulse of the ``masked`` source. With at least ``MAX_MASK_WIDTH`` steps,
#: consecutive delays are taken from fresh register bits rather than from shifted copies of the
#: previous delay; 16 is coprime with ``2**32 - 1``, so the sequence still has the full period.
MASKED_STEPS = 16

#: Key and IV of the ``keyed`` source (Trivium), in bits.
KEY_BITS = 80
IV_BITS = 80

#: Trivium rounds per clock cycle of the ``keyed`` source: keystream bits made per cycle. Pulses
#: are at least two cycles apart and take at most ``MAX_MASK_WIDTH`` bits, so 8 would do; 16
#: keeps a full delay in hand at every rate.
KEYED_ROUNDS = 16

#: Cycles of the 1152 initialisation rounds (4 x 288) at ``KEYED_ROUNDS`` a cycle.
KEYED_INIT_CYCLES = 4 * 288 // KEYED_ROUNDS

#: Longest wait of a run start for the keyed source, in cycles: from the cycle of the load that
#: (re)keys it to the first cycle in which the scheduler may run (load, initialisation, first
#: 16 keystream bits). The first pulse comes at most this many cycles later than it would in
#: another mode (measured in ``tests/test_keyed.py``).
KEYED_START_CYCLES = KEYED_INIT_CYCLES + 2

#: Width of a delay, in bits.
DELAY_WIDTH = MAX_LENGTH

#: Width of the period setting, in bits: down to 0.02 Hz at 80 MHz.
PERIOD_WIDTH = 32

#: Width of the laser pulse width setting, in bits.
PULSE_WIDTH_WIDTH = 16


#: Default width of a histogram bank's word address, ``bank_bits``: a bank of ``2**16`` bins,
#: 64 pixels of 1024 bins or one of 8192 (the ULX3S build, in block RAM; the iCEBreaker's holds
#: ``2**14``, one SPRAM per bank). A pixel split fits when ``pixel_bits + 13 - bin_shift <=
#: bank_bits``.
BANK_BITS = 16

#: Narrowest bank of a whole board: one pixel of 8192 bins (the registers' reset values).
MIN_BANK_BITS = 13

#: Widest bank: 64 pixels of 8192 bins.
MAX_BANK_BITS = 19


class DelayMode(enum.Enum, shape=2):
    """Source of the pseudorandom delay ``T_rnd``, in clock cycles."""
    #: No delay: the laser fires on the nominal schedule.
    OFF    = 0
    #: Complete m-sequence of an ``L``-bit register, one state per pulse; delay ``R = state - 1``,
    #: so ``R`` runs over ``0 … 2**L - 2`` once per period (equation 9 and Table 2 of the paper).
    MSEQ   = 1
    #: The ``Wm`` least significant bits of a 32-bit register that takes ``MASKED_STEPS`` steps per
    #: pulse; delay from ``0`` to ``2**Wm - 1``.
    MASKED = 2
    #: The Trivium keystream of an 80-bit key and IV (:mod:`fliss.sim.models.trivium`): pulse ``k``'s
    #: delay is the ``Wm``-bit integer whose bit ``j`` is keystream bit ``z(k Wm + j + 1)``;
    #: delay from ``0`` to ``2**Wm - 1``, as ``MASKED``.
    KEYED  = 3


def check_widths(period_width, pulse_width_width):
    """Refuse setting widths the scheduler cannot take: a period of 17 to
    :data:`PERIOD_WIDTH` bits (its timers count in 16-bit halves), a pulse width of 1 to
    :data:`PULSE_WIDTH_WIDTH` bits."""
    if not isinstance(period_width, int) or not 17 <= period_width <= PERIOD_WIDTH:
        raise ValueError(f"Period width must be an integer from 17 to {PERIOD_WIDTH} bits, "
                         f"not {period_width!r}")
    if not isinstance(pulse_width_width, int) or not 1 <= pulse_width_width <= PULSE_WIDTH_WIDTH:
        raise ValueError(f"Pulse width width must be an integer from 1 to {PULSE_WIDTH_WIDTH} "
                         f"bits, not {pulse_width_width!r}")


def mean_delay(mode, length, mask_width):
    """Mean delay of a source over one whole sequence period, in clock cycles, as an exact
    fraction (settings as the registers hold them, not checked: see
    :func:`fliss.sim.models.delay.mean_delay`).

    ``mseq``: the states ``1 … 2**L - 1`` each once, so ``R`` averages ``2**(L-1) - 1``.
    ``masked``: over the ``2**32 - 1`` non-zero states, each non-zero value of the low ``Wm``
    bits occurs ``2**(32-Wm)`` times and zero ``2**(32-Wm) - 1`` times.
    ``keyed``: that of uniform ``Wm``-bit delays, ``(2**Wm - 1) / 2`` (an ideal keystream's).
    """
    mode = DelayMode(mode)
    if mode == DelayMode.KEYED:
        return Fraction((1 << mask_width) - 1, 2)
    if mode == DelayMode.MSEQ:
        return Fraction((1 << length) - 2, 2)
    if mode == DelayMode.MASKED:
        per_value = 1 << (MASKED_LENGTH - mask_width)
        total = per_value * ((1 << mask_width) - 1) * (1 << mask_width) // 2
        return Fraction(total, (1 << MASKED_LENGTH) - 1)
    return Fraction(0)
