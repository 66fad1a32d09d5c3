"""Bit-exact model of :class:`fliss.hdl.delay.DelaySource`."""

import numpy as np

from ..hdl.settings import DelayMode, MAX_LENGTH, MAX_MASK_WIDTH, MASKED_LENGTH, MASKED_STEPS
from . import lfsr


__all__ = ["DelayMode", "parse_mode", "check_settings", "delays", "max_delay", "mean_delay",
           "sequence_period"]


def parse_mode(mode):
    """A :class:`DelayMode` from itself or its name (``"off"``, ``"mseq"``, ``"masked"``)."""
    if isinstance(mode, DelayMode):
        return mode
    try:
        return DelayMode[str(mode).upper()]
    except KeyError:
        names = ", ".join(m.name.lower() for m in DelayMode)
        raise ValueError(f"Delay mode must be one of {names}, not {mode!r}") from None


def check_settings(mode, *, length=None, mask_width=None, seed=1):
    """Validate delay settings as a user gives them; return the mode.

    ``length`` is needed for ``mseq``, ``mask_width`` for ``masked``. The seed must be a non-zero
    state of the register: from 1 to ``2**L - 1`` (``2**32 - 1`` for ``masked``).
    """
    mode = parse_mode(mode)
    if mode == DelayMode.MSEQ:
        if length is None:
            raise ValueError("The mseq delay source needs a register length L")
        lfsr.check_length(length)
        bits = length
    elif mode == DelayMode.MASKED:
        if mask_width is None:
            raise ValueError("The masked delay source needs a mask width Wm")
        if not isinstance(mask_width, (int, np.integer)) or not 1 <= mask_width <= MAX_MASK_WIDTH:
            raise ValueError(f"Mask width must be an integer from 1 to {MAX_MASK_WIDTH}, "
                             f"not {mask_width!r}")
        bits = MASKED_LENGTH
    else:
        bits = MAX_LENGTH
    if not isinstance(seed, (int, np.integer)) or not 1 <= seed < (1 << bits):
        raise ValueError(f"Seed must be an integer from 1 to {(1 << bits) - 1} (a non-zero "
                         f"{bits}-bit register state), not {seed!r}")
    return mode


def delays(mode, count, *, length=None, mask_width=None, seed=1):
    """The first ``count`` delays, in clock cycles, after a load; a ``numpy.int64`` array."""
    mode = check_settings(mode, length=length, mask_width=mask_width, seed=seed)
    if mode == DelayMode.MSEQ:
        return lfsr.states(length, seed, count).astype(np.int64) - 1
    if mode == DelayMode.MASKED:
        states = lfsr.states(MASKED_LENGTH, seed, count, steps=MASKED_STEPS)
        return (states & np.uint64((1 << mask_width) - 1)).astype(np.int64)
    return np.zeros(count, dtype=np.int64)


def max_delay(mode, *, length=None, mask_width=None):
    """Largest delay of the source, in clock cycles."""
    mode = check_settings(mode, length=length, mask_width=mask_width)
    if mode == DelayMode.MSEQ:
        return (1 << length) - 2
    if mode == DelayMode.MASKED:
        return (1 << mask_width) - 1
    return 0


def sequence_period(mode, *, length=None, mask_width=None):
    """Number of pulses after which the delay sequence repeats."""
    mode = check_settings(mode, length=length, mask_width=mask_width)
    if mode == DelayMode.MSEQ:
        return (1 << length) - 1
    if mode == DelayMode.MASKED:
        return (1 << MASKED_LENGTH) - 1
    return 1


def mean_delay(mode, *, length=None, mask_width=None):
    """Mean delay over one whole sequence period, in clock cycles, as an exact fraction.

    ``mseq``: the states ``1 … 2**L - 1`` each once, so ``R`` averages ``2**(L-1) - 1``.
    ``masked``: over the ``2**32 - 1`` non-zero states, each non-zero value of the low ``Wm``
    bits occurs ``2**(32-Wm)`` times and zero ``2**(32-Wm) - 1`` times.
    """
    from fractions import Fraction
    mode = check_settings(mode, length=length, mask_width=mask_width)
    if mode == DelayMode.MSEQ:
        return Fraction((1 << length) - 2, 2)
    if mode == DelayMode.MASKED:
        per_value = 1 << (MASKED_LENGTH - mask_width)
        total = per_value * ((1 << mask_width) - 1) * (1 << mask_width) // 2
        return Fraction(total, (1 << MASKED_LENGTH) - 1)
    return Fraction(0)
