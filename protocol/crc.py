"""The link's CRC-16 (:data:`fliss.hdl.protocol.CRC_POLY`), the software half of
:mod:`fliss.hdl.link.crc`."""

import binascii

from ..hdl.protocol import CRC_INIT, CRC_POLY, CRC_WIDTH


__all__ = ["CRC_TABLE", "crc16"]


def _crc_table():
    top = 1 << (CRC_WIDTH - 1)
    mask = (1 << CRC_WIDTH) - 1
    table = []
    for byte in range(256):
        crc = byte << (CRC_WIDTH - 8)
        for _ in range(8):
            crc = ((crc << 1) ^ CRC_POLY) & mask if crc & top else (crc << 1) & mask
        table.append(crc)
    return table


#: CRC of each byte value (the byte-at-a-time table of :data:`CRC_POLY`), for table-driven CRCs.
CRC_TABLE = tuple(_crc_table())


def _crc16_table_driven(data, crc=CRC_INIT):
    # The definition, one table lookup per byte; tests hold binascii to it.
    for byte in bytes(data):
        crc = ((crc << 8) & 0xffff) ^ CRC_TABLE[(crc >> 8) ^ byte]
    return crc


def crc16(data, crc=CRC_INIT):
    """CRC-16/IBM-3740 of ``data`` (bytes-like), continuing from ``crc``.

    :func:`binascii.crc_hqx` computes this CRC (polynomial 0x1021, MSB first, no final XOR) in
    C; it is used when the protocol's CRC is that one.
    """
    if _CRC_IS_HQX:
        return binascii.crc_hqx(data, crc)
    return _crc16_table_driven(data, crc)


_CRC_IS_HQX = (CRC_WIDTH, CRC_POLY) == (16, 0x1021) and \
    binascii.crc_hqx(b"123456789", CRC_INIT) == _crc16_table_driven(b"123456789")
