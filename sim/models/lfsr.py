"""Bit-exact model of :class:`fliss.hdl.delay.lfsr.Lfsr`.

A register step is a linear map over GF(2), so ``k`` steps are one precomputed map. Long runs of
states are generated a block at a time: the next block is the current block mapped by the
block-length jump, one numpy operation per block.
"""

from functools import lru_cache

import numpy as np

from ...hdl.delay.lfsr import POLYNOMIALS, MIN_LENGTH, MAX_LENGTH


__all__ = ["POLYNOMIALS", "check_length", "load", "step", "states"]


def check_length(length):
    """Raise :exc:`ValueError` unless ``length`` is a supported register length."""
    if not isinstance(length, (int, np.integer)) or not MIN_LENGTH <= length <= MAX_LENGTH:
        raise ValueError(f"LFSR length must be an integer from {MIN_LENGTH} to {MAX_LENGTH}, "
                         f"not {length!r}")


def load(seed, length):
    """State loaded from ``seed``: its low ``length`` bits, or 1 if those are all zero."""
    check_length(length)
    state = int(seed) & ((1 << length) - 1)
    return state or 1


def step(state, length):
    """One step of the right-shifting Galois register."""
    taps = POLYNOMIALS[length] >> 1
    return (state >> 1) ^ (taps if state & 1 else 0)


# A linear map on `length`-bit states is kept as the images of the basis vectors.

def _apply(columns, state):
    result = 0
    bit = 0
    while state:
        if state & 1:
            result ^= columns[bit]
        state >>= 1
        bit += 1
    return result


def _compose(outer, inner):
    return tuple(_apply(outer, column) for column in inner)


@lru_cache(maxsize=None)
def _jump(length, count):
    """The map of ``count`` register steps."""
    result = tuple(1 << bit for bit in range(length))
    power = tuple(step(1 << bit, length) for bit in range(length))
    while count:
        if count & 1:
            result = _compose(power, result)
        power = _compose(power, power)
        count >>= 1
    return result


@lru_cache(maxsize=None)
def _byte_tables(length, count):
    # Image of every value of each byte of the state, for a vectorised map.
    columns = _jump(length, count)
    tables = np.zeros(((length + 7) // 8, 256), dtype=np.uint64)
    for byte in range(tables.shape[0]):
        for value in range(256):
            tables[byte, value] = _apply(columns, (value << (8 * byte)) & ((1 << length) - 1))
    return tables


def _apply_vector(tables, states):
    result = np.zeros_like(states)
    for byte in range(tables.shape[0]):
        result ^= tables[byte][(states >> np.uint64(8 * byte)) & np.uint64(0xff)]
    return result


def states(length, seed, count, *, steps=1, block=4096):
    """The first ``count`` states after loading ``seed``, taking ``steps`` steps between states.

    Returns a ``numpy.uint64`` array whose first element is the loaded seed.
    """
    check_length(length)
    if count < 0:
        raise ValueError(f"Count must not be negative, not {count}")
    out = np.empty(count, dtype=np.uint64)
    if count == 0:
        return out
    head = min(count, block)
    jump = _jump(length, steps)
    state = load(seed, length)
    for index in range(head):
        out[index] = state
        state = _apply(jump, state)
    if count > head:
        tables = _byte_tables(length, steps * head)
        for start in range(head, count, head):
            stop = min(start + head, count)
            out[start:stop] = _apply_vector(tables, out[start - head:start])[:stop - start]
    return out
