"""The PTU header and T3 records of a raw capture, after PicoQuant's documented layout.

PicoQuant's file-format documentation (github.com/PicoQuant/PicoQuant-Time-Tagged-File-Format-
Demos, ``doc/``) defines both. The header: the magic ``PQTTTR``, the version ``1.0.00``, then
tags of 48 bytes (a 32-byte name, an ``int32`` index, a ``uint32`` type, 8 bytes of value; a
string's value is its length in bytes, the text following, padded to 8 bytes) up to
``Header_End``. A ``GenericT3`` record is a little-endian ``uint32``: bits 0-9 ``nsync`` (the
sync count modulo 1024), 10-24 ``dtime``, 25-30 the channel, bit 31 special; a special record
of channel 63 is an overflow, its ``nsync`` the number of 1024-sync wraps it stands for.

ptufile writes PTU files of histograms only (T3 image mode: one record per count, at made-up
sync counts), so events, whose sync counts are the data, are written here; ptufile and tttrlib
read the files back in the tests.
"""

import contextlib
import datetime
import logging
import struct

import numpy as np


__all__ = ["GENERIC_T3", "WRAP", "tag", "header", "number_records_at", "t3_records"]


#: ``TTResultFormat_TTTRRecType`` of the MultiHarp / PicoHarp 330 T3 record.
GENERIC_T3 = 0x00010307
#: Sync counts per overflow of ``nsync``.
WRAP = 1 << 10
#: Most wraps one overflow record stands for.
_MAX_WRAPS = WRAP - 1

_EMPTY, _BOOL, _INT, _FLOAT = 0xFFFF0008, 0x00000008, 0x10000008, 0x20000008
_DATETIME, _STRING = 0x21000008, 0x4001FFFF
_MAGIC = b"PQTTTR\0\0" + b"1.0.00\0\0"


def tag(name, value, index=-1):
    """One header tag: ``None`` (empty), bool, int, float, :class:`datetime.datetime` (naive
    UTC) or str."""
    ident = name.encode("ascii")
    if len(ident) > 31:
        raise ValueError(f"PTU tag name {name!r} is longer than 31 characters")
    head = ident.ljust(32, b"\0") + struct.pack("<i", index)
    if value is None:
        return head + struct.pack("<I8x", _EMPTY)
    if isinstance(value, (bool, np.bool_)):
        return head + struct.pack("<Iq", _BOOL, int(bool(value)))
    if isinstance(value, (int, np.integer)):
        return head + struct.pack("<Iq", _INT, int(value))
    if isinstance(value, (float, np.floating)):
        return head + struct.pack("<Id", _FLOAT, float(value))
    if isinstance(value, datetime.datetime):
        days = (value - datetime.datetime(1899, 12, 30)) / datetime.timedelta(days=1)
        return head + struct.pack("<Id", _DATETIME, days)
    if isinstance(value, str):
        text = value.encode("windows-1252", errors="replace") + b"\0"
        text += b"\0" * (-len(text) % 8)
        return head + struct.pack("<Iq", _STRING, len(text)) + text
    raise TypeError(f"PTU tag {name!r}: no tag type for {type(value).__name__}")


def header(tags):
    """The header of a PTU file with ``tags`` (a dict, in order), ended by ``Header_End``."""
    return _MAGIC + b"".join(tag(name, value) for name, value in tags.items()) + \
        tag("Header_End", None)


def number_records_at(head):
    """Where, in the header ``head``, the 8-byte value of ``TTResult_NumberOfRecords`` is: a
    writer that counts its records as it goes writes the count there at the end."""
    return head.index(b"TTResult_NumberOfRecords".ljust(32, b"\0")) + 40


def t3_records(sync, dtime, channel, before=0):
    """``GenericT3`` records (``uint32``) of photons at sync counts ``sync`` (non-decreasing,
    from ``before``, the sync count of the photon before them: 0 at the start of a file), with
    ``dtime`` (< 2**15) and ``channel`` (< 64), each preceded by the overflow records that bring
    the sync count to it. Records made run by run, each from the last sync of the run before,
    are those made at once."""
    sync = np.asarray(sync, dtype=np.int64)
    wraps = np.diff(sync // WRAP, prepend=before // WRAP)
    overflows = -(-wraps // _MAX_WRAPS)
    ends = np.cumsum(overflows)
    records = np.empty(len(sync) + int(ends[-1] if len(ends) else 0), dtype=np.uint32)
    at = np.arange(len(sync)) + ends
    records[at] = ((np.asarray(channel, dtype=np.uint32) << 25)
                   | (np.asarray(dtime, dtype=np.uint32) << 10) | (sync % WRAP).astype(np.uint32))
    # Overflow records: each of a photon's stands for 1023 wraps but its last, for the rest.
    owner = np.repeat(np.arange(len(sync)), overflows)
    place = np.arange(len(owner)) - (ends - overflows)[owner]
    last = place == overflows[owner] - 1
    counts = np.where(last, wraps[owner] - _MAX_WRAPS * (overflows[owner] - 1), _MAX_WRAPS)
    free = np.ones(len(records), dtype=bool)
    free[at] = False
    records[free] = np.uint32(1 << 31 | 63 << 25) | counts.astype(np.uint32)
    return records


class _Notes(logging.Handler):
    # ptufile's complaints about a file it reads anyway.
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages = []

    def emit(self, record):
        self.messages.append(record.getMessage())


@contextlib.contextmanager
def ptufile_notes():
    """What ptufile logs (its complaints about a file it reads anyway) while in the block,
    kept from the terminal: yields a handler whose ``messages`` are the lines it logged."""
    notes, logger = _Notes(), logging.getLogger("ptufile")
    logger.addHandler(notes)
    propagate, logger.propagate = logger.propagate, False
    try:
        yield notes
    finally:
        logger.removeHandler(notes)
        logger.propagate = propagate
