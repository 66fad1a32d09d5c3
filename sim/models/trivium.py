"""Trivium keystream generator, the reference model of the ``keyed`` delay source.

Trivium (C. De Cannière and B. Preneel, eSTREAM portfolio, ISO/IEC 29192-3) is a 288-bit
nonlinear shift register loaded with an 80-bit key and an 80-bit IV and run for 1152 rounds before
its first output bit. This model produces the keystream of the eSTREAM reference code, so that it
equals the published test vectors.

Keys and IVs are given as 10 bytes (``bytes``), as the test vectors print them, or as the 80-bit
integer those bytes spell in hex (``int.from_bytes(key, "big")``: ``0x80000000000000000000`` is the
key ``80 00 00 00 00 00 00 00 00 00``). The reference code reads the bytes as one little-endian
number ``k`` and loads ``s[i] = bit 80 - i of k`` (``i`` from 1 to 80); keystream bytes take bits
least significant first.

The model runs 64 rounds in one step: no tap is nearer than 66 rounds to a register's input, so
64 rounds read only bits of the state before the step.
"""

import numpy as np

from ...hdl.delay.settings import KEY_BYTES, as_int


__all__ = ["KEY_BYTES", "INIT_ROUNDS", "Trivium",
           "keystream", "keystream_bytes", "keyed_delays"]


#: Rounds run after loading, before the first keystream bit (4 × 288).
INIT_ROUNDS = 4 * 288

_WORD = 64
_MASK = (1 << _WORD) - 1


def _reversed_bytes(value):
    """The reference code's number ``k`` from the big-endian integer of the printed bytes."""
    return int.from_bytes(value.to_bytes(KEY_BYTES, "big"), "little")


class Trivium:
    """The keystream of one key and IV, produced on demand.

    The state is three integers ``a``, ``b``, ``c`` holding ``s1 … s93``, ``s94 … s177`` and
    ``s178 … s288``, the highest-numbered bit of each register at bit 0 (so ``s93`` is bit 0 of
    ``a`` and ``s1`` its bit 92).

    Parameters
    ----------
    key, iv : bytes or int
        See the module documentation.
    """

    def __init__(self, key, iv):
        key, iv = as_int(key, "key"), as_int(iv, "IV")
        self.a = _reversed_bytes(key) << 13
        self.b = _reversed_bytes(iv) << 4
        self.c = 0b111
        for _ in range(INIT_ROUNDS // _WORD):
            self._rounds()
        self._pending = np.zeros(0, dtype=np.uint8)

    def _rounds(self):
        """Run 64 rounds; the 64 output bits, the first at bit 0."""
        a, b, c = self.a, self.b, self.c
        t1 = (a >> 27) ^ a
        t2 = (b >> 15) ^ b
        t3 = (c >> 45) ^ c
        z = (t1 ^ t2 ^ t3) & _MASK
        t1 = (t1 ^ ((a >> 2) & (a >> 1)) ^ (b >> 6)) & _MASK
        t2 = (t2 ^ ((b >> 2) & (b >> 1)) ^ (c >> 24)) & _MASK
        t3 = (t3 ^ ((c >> 2) & (c >> 1)) ^ (a >> 24)) & _MASK
        self.a = (a >> _WORD) | (t3 << 29)
        self.b = (b >> _WORD) | (t1 << 20)
        self.c = (c >> _WORD) | (t2 << 47)
        return z

    def bits(self, count):
        """The next ``count`` keystream bits as a ``uint8`` array of 0 and 1."""
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
            raise ValueError(f"Bit count must be a non-negative integer, not {count!r}")
        need = count - len(self._pending)
        words = max(0, -(-need // _WORD))
        packed = np.array([self._rounds() for _ in range(words)], dtype=np.uint64)
        fresh = np.unpackbits(packed.view(np.uint8), bitorder="little")
        stream = np.concatenate((self._pending, fresh))
        self._pending = stream[count:]
        return stream[:count]


def keystream(key, iv, count):
    """The first ``count`` keystream bits ``z(1) … z(count)`` of ``key`` and ``iv`` (``uint8``)."""
    return Trivium(key, iv).bits(count)


def keystream_bytes(key, iv, count):
    """The first ``count`` keystream bytes, bits least significant first (as the test vectors
    print them)."""
    return np.packbits(keystream(key, iv, 8 * count), bitorder="little").tobytes()


def keyed_delays(key, iv, mask_width, count):
    """Delays of the ``keyed`` source: pulse ``k``'s delay is the ``mask_width``-bit integer
    whose bit ``j`` is keystream bit ``z(k * mask_width + j + 1)``."""
    if isinstance(mask_width, bool) or not isinstance(mask_width, (int, np.integer)) or \
            not 1 <= mask_width <= 16:
        raise ValueError(f"Mask width must be an integer from 1 to 16, not {mask_width!r}")
    bits = keystream(key, iv, mask_width * count).reshape(count, mask_width)
    return (bits.astype(np.int64) << np.arange(mask_width)).sum(axis=1)
