"""The header of a PTU file checked before ptufile reads it, so that a file that is not a PTU,
or not a whole one, is refused with its reason in one line (ptufile's own errors for a broken
header are Python's: "cannot access local variable 'tagid'").

The layout (PicoQuant's file-format documentation, as in :mod:`.ptu_records`): the magic
``PQTTTR``, 8 bytes of version, then tags of 48 bytes (a 32-byte name, an ``int32`` index, a
``uint32`` type, 8 bytes of value; the types of variable size give their size in bytes there,
the data following) up to ``Header_End``, then the records.
"""

import math
import os
import struct
from dataclasses import dataclass

from ..errors import FormatError


__all__ = ["MAGIC", "PtuHeader", "read_header"]


#: The first 8 bytes of a PTU file.
MAGIC = b"PQTTTR\0\0"

#: Tag types whose value is in the tag's 8 bytes, and how to read it.
_FIXED = {
    0xFFFF0008: None,       # Empty8
    0x00000008: "<q",       # Bool8
    0x10000008: "<q",       # Int8
    0x11000008: "<q",       # BitSet64
    0x12000008: "<q",       # Color8
    0x20000008: "<d",       # Float8
    0x21000008: "<d",       # TDateTime
}
#: Tag types whose 8 bytes give the size of the data after the tag.
_SIZED = {0x2001FFFF: "Float8Array", 0x4001FFFF: "AnsiString", 0x4002FFFF: "WideString",
          0xFFFFFFFF: "BinaryBlob"}
_ANSI = 0x4001FFFF

#: The tags that are whole numbers.
_WHOLE = ("Measurement_Mode", "TTResultFormat_TTTRRecType", "TTResultFormat_BitsPerRecord",
          "TTResult_NumberOfRecords")

_TAG = struct.Struct("<32siI8s")

#: The tags a T3 file cannot be read without.
_NEEDED = ("Measurement_Mode", "TTResultFormat_TTTRRecType", "TTResultFormat_BitsPerRecord",
           "MeasDesc_Resolution")


@dataclass
class PtuHeader:
    """A PTU file's tags (the numbers and texts; the last of a name that comes several times),
    where its records start and how many bytes of them the file holds."""
    tags: dict
    data_offset: int
    data_bytes: int


def read_header(path) -> PtuHeader:
    """The header of the PTU file ``path``; :exc:`FormatError` of one line, ``"PATH: not a PTU
    file (why)"``, for a file that is not a PTU file or not a whole one."""
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as f:
            return _read(f, size, path)
    except OSError as error:
        raise FormatError(f"cannot read {path}: {(error.strerror or str(error)).lower()}") \
            from None


def _refuse(path, why):
    return FormatError(f"{path}: not a PTU file ({why})")


def _read(f, size, path):
    if size == 0:
        raise _refuse(path, "it is empty")
    head = f.read(16)
    if head[:8] != MAGIC:
        raise _refuse(path, "it does not begin with PQTTTR, the mark of a PTU file")
    if len(head) < 16:
        raise _refuse(path, f"it ends at byte {size}, in its header")
    tags = {}
    while True:
        at = f.tell()
        raw = f.read(_TAG.size)
        if len(raw) < _TAG.size:
            raise _refuse(path, f"it ends at byte {size}, in its header, before Header_End")
        ident, _, kind, value = _TAG.unpack(raw)
        name = ident.split(b"\0")[0].decode("ascii", errors="replace")
        if name == "Header_End":
            break
        if kind in _FIXED:
            if _FIXED[kind] is not None:
                tags[name] = struct.unpack(_FIXED[kind], value)[0]
            continue
        if kind not in _SIZED:
            raise _refuse(path, f"the tag at byte {at}, {name!r}, has no PTU type "
                                f"(0x{kind:08X})")
        length = struct.unpack("<q", value)[0]
        if length < 0 or f.tell() + length > size:
            raise _refuse(path, f"its {_SIZED[kind]} tag {name!r} at byte {at} holds "
                                f"{length} bytes, past the end of the file at byte {size}")
        data = f.read(length)
        if kind == _ANSI:
            tags[name] = data.split(b"\0")[0].decode("windows-1252", errors="replace")
    header = PtuHeader(tags, f.tell(), size - f.tell())
    _check_t3(header, path)
    return header


def _check_t3(header, path):
    tags = header.tags
    missing = [name for name in _NEEDED if name not in tags]
    if missing:
        raise _refuse(path, f"its header has no {', '.join(missing)}")
    for name in _WHOLE:
        if name in tags and not isinstance(tags[name], int):
            raise _refuse(path, f"its {name} is {tags[name]!r}, not a whole number")
    mode = tags["Measurement_Mode"]
    if mode == 2:
        raise FormatError(f"{path}: a T2 PTU file (time tags without a laser sync) holds no "
                          f"TCSPC histogram; fliss reads T3 files")
    if mode != 3:
        raise FormatError(f"{path}: its Measurement_Mode is {mode!r}, not 3 (T3 records); "
                          f"fliss reads T3 files")
    bits = tags["TTResultFormat_BitsPerRecord"]
    if bits != 32:
        raise _refuse(path, f"its records are of {bits} bits; T3 records are of 32")
    resolution = tags["MeasDesc_Resolution"]
    if not isinstance(resolution, float) or not 0 < resolution < math.inf:
        raise _refuse(path, f"its MeasDesc_Resolution, the width of a TCSPC bin, is "
                            f"{resolution!r} s")
    count = tags.get("TTResult_NumberOfRecords", 0)
    if header.data_bytes % 4:
        raise _refuse(path, f"it ends in the middle of a record: {header.data_bytes} bytes "
                            f"of records are not a whole number of 4-byte records")
    if count > 0 and count * 4 > header.data_bytes:
        raise _refuse(path, f"it is cut short: its header announces {count} records, "
                            f"{count * 4} bytes, and {header.data_bytes} follow it")
