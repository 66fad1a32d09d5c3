"""COBS encoding of packets on the wire, the software half of :mod:`fliss.hdl.link.cobs`."""

from ..hdl.protocol import COBS_MAX_RUN


__all__ = ["CobsError", "cobs_encode", "cobs_decode"]


class CobsError(ValueError):
    """COBS-encoded bytes that no packet encodes to."""


def cobs_encode(data):
    """COBS encoding of ``data`` (Cheshire and Baker): no zero byte in the result.

    A block is a code byte ``n`` and ``n - 1`` non-zero bytes. It stands for those bytes and a
    zero when ``n < 0xff``; a ``0xff`` block holds :data:`COBS_MAX_RUN` bytes and no zero. The
    data is encoded with a zero appended, which the decoder drops again; when the data ends
    with a full ``0xff`` block, that zero needs no block of its own. Output length:
    ``len(data) + 1 + (len(data) - 1) // 254`` (1 for empty data).
    """
    out = bytearray()
    run = bytearray()
    full = False    # the last byte closed a full block
    for byte in bytes(data):
        full = False
        if byte == 0:
            out.append(len(run) + 1)
            out += run
            run.clear()
        else:
            run.append(byte)
            if len(run) == COBS_MAX_RUN:
                out.append(COBS_MAX_RUN + 1)
                out += run
                run.clear()
                full = True
    if not full:
        out.append(len(run) + 1)
        out += run
    return bytes(out)


def cobs_decode(data):
    """Inverse of :func:`cobs_encode`; raises :exc:`CobsError` on a zero byte or a cut block."""
    data = bytes(data)
    out = bytearray()
    index = 0
    while index < len(data):
        code = data[index]
        if code == 0:
            raise CobsError(f"zero byte at offset {index}")
        block = data[index + 1:index + code]
        if len(block) != code - 1:
            raise CobsError(f"block at offset {index} is cut short")
        if 0 in block:
            raise CobsError(f"zero byte in block at offset {index}")
        out += block
        index += code
        if code != COBS_MAX_RUN + 1 and index < len(data):
            out.append(0)
    if not data:
        raise CobsError("empty")
    return bytes(out)
