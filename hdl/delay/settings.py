"""Limits of the delay core's settings: the numbers the register map, the gateware and the models
share.

A definitions module: it imports no gateware, so :mod:`fliss.hdl.registers` can build the register
map from it and the blocks (:mod:`.lfsr`, :mod:`.source`, :mod:`.scheduler`) can import it. The
delay modes are in :mod:`.modes`. The ``keyed`` source's key and IV are read here as users and
the test vectors write them (:func:`parse_hex`, :func:`as_int`).
"""

import numbers


__all__ = ["MIN_LENGTH", "MAX_LENGTH", "MAX_MASK_WIDTH", "MASKED_LENGTH", "MASKED_STEPS",
           "KEY_BITS", "IV_BITS", "LAST_IV", "KEY_BYTES", "as_int", "parse_hex", "KEYED_ROUNDS", "KEYED_INIT_CYCLES", "KEYED_START_CYCLES",
           "DELAY_WIDTH", "PERIOD_WIDTH",
           "PULSE_WIDTH_WIDTH", "BANK_BITS", "MIN_BANK_BITS", "MAX_BANK_BITS",
           "check_widths"]


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

#: The last IV of the ``keyed`` source under one key: its restarts count the IV up and never
#: wrap around past this one to 0 (the source is spent instead, until a key is written).
LAST_IV = (1 << IV_BITS) - 1

#: Key and IV length in bytes, as the Trivium test vectors print them.
KEY_BYTES = KEY_BITS // 8

#: Trivium rounds per clock cycle of the ``keyed`` source: keystream bits made per cycle. Pulses
#: are at least two cycles apart and take at most ``MAX_MASK_WIDTH`` bits, so 8 would do; 16
#: keeps a full delay in hand at every rate.
KEYED_ROUNDS = 16

#: Cycles of the 1152 initialisation rounds (4 x 288) at ``KEYED_ROUNDS`` a cycle.
KEYED_INIT_CYCLES = 4 * 288 // KEYED_ROUNDS

#: Longest wait of a run start for the keyed source, in cycles: from the cycle of the load that
#: (re)keys it to the first cycle in which the scheduler may run (load, initialisation, first
#: 16 keystream bits). The first pulse comes at most this many cycles later than it would in
#: another mode (measured in ``tests/gateware/test_keyed.py``).
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


def as_int(value, what="key"):
    """The 80-bit integer of a key or IV given as 10 bytes or as an integer; ``ValueError`` with
    one line for anything else."""
    if isinstance(value, (bytes, bytearray)):
        if len(value) != KEY_BYTES:
            raise ValueError(f"A Trivium {what} is {KEY_BYTES} bytes (80 bits), "
                             f"not {len(value)}")
        return int.from_bytes(value, "big")
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ValueError(f"A Trivium {what} is 10 bytes or an 80-bit integer, not {value!r}")
    if not 0 <= int(value) < 1 << 80:
        raise ValueError(f"A Trivium {what} must be an 80-bit integer (0 to 2**80 - 1), "
                         f"not {value:#x}")
    return int(value)


def parse_hex(text, what="key", *, exact=False, alternative=None):
    """The 80-bit integer of a key or IV written in hex as the test vectors print it: up to 20
    hex digits, spaces, ``_`` and a leading ``0x`` allowed (``80 00 00 00 00 00 00 00 00 00`` is
    ``0x80000000000000000000``); with ``exact``, all 20 digits (a key: ``12345`` would be read as
    ``00000000000000012345``, a key nobody meant). ``ValueError`` with one line for anything
    else, naming ``alternative`` (``"random"``) if the caller takes one."""
    digits = str(text).replace(" ", "").replace("_", "")
    if digits[:2].lower() == "0x":
        digits = digits[2:]
    hex_digits = bool(digits) and all(c in "0123456789abcdefABCDEF" for c in digits)
    if not hex_digits or len(digits) > 2 * KEY_BYTES or \
            (exact and len(digits) != 2 * KEY_BYTES):
        count = f" ({len(digits)} digit{'s' * (len(digits) != 1)})" if hex_digits else ""
        other = f" or {alternative}" if alternative else ""
        raise ValueError(f"A Trivium {what} is {'' if exact else 'up to '}20 hex digits (80 bits, "
                         f"as the test vectors print it){other}, not {text!r}{count}")
    return int(digits, 16)
