"""The Trivium model against the published eSTREAM test vectors and a round-by-round
implementation written from the specification."""

import numpy as np
import pytest

from fliss.sim.models import trivium


# eSTREAM Trivium test vectors (verified.test-vectors): (key, IV, first keystream byte, bytes).
VECTORS = [
    # Set 1, vector 0.
    ("80000000000000000000", "00000000000000000000", 0, "38EB86FF730D7A9C"),
    # Set 6, vector 0.
    ("0053A6F94C9FF24598EB", "0D74DB42A91077DE45AC", 0,
     "F4CD954A717F26A7D6930830C4E7CF08"),
    ("0053A6F94C9FF24598EB", "0D74DB42A91077DE45AC", 65472, "C04C24A6938C8AF8"),
]


@pytest.mark.parametrize("key, iv, start, expected", VECTORS)
def test_published_vectors(key, iv, start, expected):
    expected = bytes.fromhex(expected)
    stream = trivium.keystream_bytes(bytes.fromhex(key), bytes.fromhex(iv),
                                     start + len(expected))
    assert stream[start:] == expected


def _specification(key, iv, count):
    """Round by round, in the specification's notation (s1 … s288, 1-based)."""
    k = int.from_bytes(key, "little")
    v = int.from_bytes(iv, "little")
    s = [0] * 289
    for i in range(1, 81):
        s[i] = (k >> (80 - i)) & 1
        s[93 + i] = (v >> (80 - i)) & 1
    s[286] = s[287] = s[288] = 1
    out = []
    for round_ in range(trivium.INIT_ROUNDS + count):
        t1, t2, t3 = s[66] ^ s[93], s[162] ^ s[177], s[243] ^ s[288]
        if round_ >= trivium.INIT_ROUNDS:
            out.append(t1 ^ t2 ^ t3)
        t1 ^= (s[91] & s[92]) ^ s[171]
        t2 ^= (s[175] & s[176]) ^ s[264]
        t3 ^= (s[286] & s[287]) ^ s[69]
        s[1:94] = [t3] + s[1:93]
        s[94:178] = [t1] + s[94:177]
        s[178:289] = [t2] + s[178:288]
    return out


def test_word_steps_equal_rounds():
    rng = np.random.default_rng(14)
    for _ in range(3):
        key, iv = rng.bytes(10), rng.bytes(10)
        assert list(trivium.keystream(key, iv, 300)) == _specification(key, iv, 300)


def test_bits_continue_across_calls():
    generator = trivium.Trivium(0x1234, 0x5678)
    pieces = np.concatenate([generator.bits(n) for n in (1, 63, 0, 65, 200)])
    assert list(pieces) == list(trivium.keystream(0x1234, 0x5678, 329))


@pytest.mark.parametrize("mask_width", [1, 6, 16])
def test_keyed_delays_take_bits_in_order(mask_width):
    key, iv = bytes.fromhex("80000000000000000000"), bytes(10)
    bits = _specification(key, iv, 5 * mask_width)
    expected = [sum(bits[k * mask_width + j] << j for j in range(mask_width)) for k in range(5)]
    assert list(trivium.keyed_delays(key, iv, mask_width, 5)) == expected


@pytest.mark.parametrize("value, message", [
    (b"\x00" * 9, "10 bytes"), (1 << 80, "80-bit"), (-1, "80-bit"), ("00", "10 bytes or"),
    (True, "10 bytes or")])
def test_bad_keys_refused(value, message):
    with pytest.raises(ValueError, match=message):
        trivium.Trivium(value, 0)
