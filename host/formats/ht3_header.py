"""The header of an HT3 file (HydraHarp 400, formats 1.0 and 2.0), read and checked so that a
file that is not an HT3 file, or not a whole one, is refused with its reason in one line
(tttrlib, handed a header cut short, reads past its end: made-up values, or no end at all).

The layout (PicoQuant's HT3 format, packed little-endian): the texts ``Ident`` (16 bytes),
``FormatVersion`` (6), creator, time and comment (306), then whole numbers and floats to byte
664, ``InpChansPresent`` there, seven more numbers, 16 bytes for each input channel, 4 (its
rate) for each, the T3 part (``SyncRate``, ``StopAfter``, ``StopReason``, ``ImgHdrSize``, the
64-bit ``nRecords``) and ``ImgHdrSize`` 4-byte words of imaging header; then the records.
"""

import math
import os
import struct
from dataclasses import dataclass

from ..errors import FormatError


__all__ = ["Ht3Header", "read_ht3_header"]


#: Where the numbers of the header are (bytes from the start) and their types.
_FIELDS = {"BitsPerRecord": (332, "<i"), "MeasurementMode": (340, "<i"),
           "Resolution": (352, "<d"), "InpChansPresent": (664, "<i")}
#: Bytes from the start to the first input channel's settings.
_CHANNELS_AT = 696
#: Most input channels of a HydraHarp 400 (8) and its imaging header's words (PicoQuant's
#: scanners write at most a few dozen): beyond them, a header that is not one.
_MOST_CHANNELS, _MOST_IMAGE_WORDS = 64, 1 << 16


@dataclass
class Ht3Header:
    """What fliss takes from an HT3 header: the format version (``"1.0"``, ``"2.0"``), the
    measurement mode (2 T2, 3 T3), the micro-time width ``resolution_s``, the sync rate, the
    records it announces, where they start (``data_offset``) and how many whole ones the file
    holds (``records``, and ``extra`` bytes after them)."""
    version: str
    mode: int
    resolution_s: float
    sync_hz: int
    announced: int
    data_offset: int
    records: int
    extra: int


def _refuse(path, why):
    return FormatError(f"{path}: not an HT3 file ({why})")


def read_ht3_header(path) -> Ht3Header:
    """The header of the HT3 file ``path``, or :exc:`FormatError` of one line: ``"PATH: not an
    HT3 file (why)"`` for one cut short or whose numbers are not those of a header."""
    try:
        size = os.path.getsize(path)
        with open(path, "rb") as f:
            head = f.read(_CHANNELS_AT)
            if len(head) < _CHANNELS_AT:
                raise _refuse(path, f"it ends at byte {size}, in its header")
            values = {name: struct.unpack_from(kind, head, at)[0]
                      for name, (at, kind) in _FIELDS.items()}
            channels = values["InpChansPresent"]
            if not 0 < channels <= _MOST_CHANNELS:
                raise _refuse(path, f"its header gives {channels} input channels")
            tail_at = _CHANNELS_AT + 20 * channels
            f.seek(tail_at)
            tail = f.read(24)
    except OSError as error:
        raise FormatError(f"cannot read {path}: {(error.strerror or str(error)).lower()}") \
            from None
    if len(tail) < 24:
        raise _refuse(path, f"it ends at byte {size}, in its header")
    sync_hz, _, _, image_words, announced = struct.unpack("<iiiiq", tail)
    if not 0 <= image_words <= _MOST_IMAGE_WORDS:
        raise _refuse(path, f"its header gives {image_words} words of imaging header")
    offset = tail_at + 24 + 4 * image_words
    if offset > size:
        raise _refuse(path, f"it ends at byte {size}, in its header (of {offset} bytes)")
    if values["BitsPerRecord"] != 32:
        raise _refuse(path, f"its records are of {values['BitsPerRecord']} bits; T3 records "
                            f"are of 32")
    resolution_ps = values["Resolution"]
    if not 0 < resolution_ps < math.inf:
        resolution_ps = math.nan            # (refused by the reader, naming the width)
    version = head[16:22].split(b"\0")[0].decode("ascii", errors="replace").strip()
    records, extra = divmod(size - offset, 4)
    return Ht3Header(version, values["MeasurementMode"], resolution_ps * 1e-12, sync_hz,
                     announced, offset, records, extra)
