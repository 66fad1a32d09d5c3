"""Software codec of the FLISS link protocol (see ``docs/protocol.md``): the software model of
the link's framing, used by the models, the testbenches and the host.

Everything about the format comes from :mod:`fliss.hdl.protocol`; this module only implements it
(it imports definitions only, so every layer above may use it):

* :func:`crc16`, :func:`cobs_encode`, :func:`cobs_decode`;
* :func:`encode_packet` / :func:`encode_frame`: a packet as packet bytes / as a wire frame;
  :class:`PacketEncoder` numbers the packets a host sends; :func:`decode_frame` checks one
  frame;
* :class:`FrameDecoder`: a streaming decoder fed with bytes as they arrive, which yields packets
  and reports every damaged frame, sequence gap and resynchronisation, and counts them;
* :func:`pack` / :func:`unpack` / :func:`unpack_from`: a payload from and to the values of its
  :mod:`amaranth.lib.data` layout (``Identity``, ``Status``, ``Nak``, ...), little-endian as the
  gateware's ``as_value()``; :func:`pack_words` / :func:`unpack_words`: arrays of u32 (or other)
  words;
* :func:`pack_events` / :func:`unpack_events`: the payload of an EVENTS packet.

:mod:`fliss.host.bulk` decodes large reads and recordings with numpy, with the same results.

The gateware (:mod:`fliss.hdl.framing`) is tested against this codec bit for bit.
"""

import binascii
import enum
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from amaranth.hdl import Shape
from amaranth.lib import data

from ..hdl.protocol import (DELIMITER, COBS_MAX_RUN, CRC_WIDTH, CRC_POLY, CRC_INIT, CRC_BYTES,
                            PacketType, Header, HEADER_BYTES, MAX_PAYLOAD, MAX_PACKET,
                            MAX_ENCODED, NakCode, LINK_COUNTERS, REGISTER_BITS, EVENT_BYTES)
from . import event as _event


__all__ = ["byte_size", "pack", "unpack", "unpack_from", "word_dtype", "pack_words",
           "unpack_words", "CRC_TABLE", "packet_type", "CobsError", "crc16", "cobs_encode",
           "cobs_decode", "Packet", "encode_packet", "encode_frame", "decode_packet",
           "decode_frame", "LinkError", "SequenceGap", "Resync", "LinkCounters", "FrameDecoder",
           "PacketEncoder", "pack_events", "unpack_events"]


# Payloads from layouts

def byte_size(layout):
    """Bytes of a payload of ``layout`` (a :class:`amaranth.lib.data.Layout` or a
    :class:`~amaranth.lib.data.Struct`), its bits rounded up to whole bytes."""
    return _layout(layout)[0]


def _writer(shape, name):
    # A function from the values of ``shape`` to its bits, with the fields looked up once.
    if isinstance(shape, data.StructLayout):
        fields = [(field_name, field.offset, _writer(field.shape, f"{name}.{field_name}"))
                  for field_name, field in shape]
        names = {field_name for field_name, _, _ in fields}

        def write_struct(value):
            if not isinstance(value, Mapping):
                raise TypeError(f"Value of {name} must be a mapping of field names, not "
                                f"{value!r}")
            if not names.issuperset(value):
                raise ValueError(f"{name} has no field {sorted(set(value) - names)[0]!r}")
            return sum(write(value[field_name]) << offset
                       for field_name, offset, write in fields if field_name in value)
        return write_struct
    if isinstance(shape, data.ArrayLayout):
        elements = [(field.offset, _writer(field.shape, f"{name}[{index}]"))
                    for index, field in shape]

        def write_array(value):
            if len(value) != len(elements):
                raise ValueError(f"{name} needs {len(elements)} elements, not {len(value)}")
            return sum(write(item) << offset for (offset, write), item in zip(elements, value))
        return write_array
    width = Shape.cast(shape).width

    def write_field(value):
        value = value.value if isinstance(value, enum.Enum) else int(value)
        if value < 0 or value >> width:
            raise ValueError(f"{name} = {value} does not fit in {width} bits")
        return value
    return write_field


def _reader(shape):
    # A function from the bits of ``shape`` to its values, with the fields looked up once.
    if isinstance(shape, (data.StructLayout, data.ArrayLayout)):
        fields = [(name, field.offset, (1 << field.width) - 1, _reader(field.shape))
                  for name, field in shape]
        if isinstance(shape, data.ArrayLayout):
            return lambda bits: [read((bits >> offset) & mask) for _, offset, mask, read in fields]
        return lambda bits: {name: read((bits >> offset) & mask)
                             for name, offset, mask, read in fields}
    return int


def pack(layout, values=None, /, **fields):
    """The payload bytes of ``layout`` with ``values`` (a dict of field names, lists for
    arrays, nested as the layout is) or keyword ``fields``: the little-endian image of the
    layout's value, as the gateware sends ``as_value()``. Fields left out are zero; enum
    members may stand for their values. Raises :exc:`ValueError` for a value that does not fit
    its field."""
    size, _, write = _layout(layout)
    return write({**(values or {}), **fields}).to_bytes(size, "little")


def _layout(layout):
    # Size in bytes, reader and writer of a layout, made once per layout (a header is read and
    # written per packet).
    try:
        return _LAYOUTS[layout]
    except KeyError:
        cast = data.Layout.cast(layout)
        _LAYOUTS[layout] = result = \
            (cast.size + 7) // 8, _reader(cast), _writer(cast, "payload")
        return result


_LAYOUTS = {}


def unpack_from(layout, payload, offset=0):
    """The values of ``layout`` (a dict, nested as the layout, arrays as lists, enum fields as
    their integers) read from ``payload`` at byte ``offset``; bytes after it are ignored."""
    size, read, _ = _layout(layout)
    chunk = bytes(payload[offset:offset + size])
    if len(chunk) != size:
        raise ValueError(f"Payload of {len(payload)} bytes is too short for {size} bytes at "
                         f"offset {offset}")
    return read(int.from_bytes(chunk, "little"))


def unpack(layout, payload):
    """The values of ``layout`` in ``payload``, which must be exactly as long as the layout (see
    :func:`unpack_from`)."""
    if len(payload) != byte_size(layout):
        raise ValueError(f"Payload of {len(payload)} bytes, not {byte_size(layout)}")
    return unpack_from(layout, payload)


def word_dtype(width=REGISTER_BITS):
    """numpy dtype of little-endian unsigned ``width``-bit words (8, 16 or 32)."""
    return np.dtype(f"<u{width // 8}")


def pack_words(words, width=REGISTER_BITS):
    """Little-endian ``width``-bit words (u32 by default), one after the other; raises
    :exc:`ValueError` for a word that does not fit."""
    values = np.asarray(words, dtype=object if not isinstance(words, np.ndarray) else None)
    if values.size and (values.min() < 0 or int(values.max()) >> width):
        raise ValueError(f"Words must be from 0 to {(1 << width) - 1}")
    return values.astype(word_dtype(width)).tobytes()


def unpack_words(payload, width=REGISTER_BITS, offset=0):
    """The little-endian ``width``-bit words (u32 by default) of ``payload`` from byte
    ``offset`` to its end, as a list of ints."""
    dtype = word_dtype(width)
    if (len(payload) - offset) % dtype.itemsize:
        raise ValueError(f"{len(payload) - offset} bytes are not a whole number of "
                         f"{dtype.itemsize}-byte words")
    return np.frombuffer(bytes(payload), dtype=dtype, offset=offset).tolist()


# CRC

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


# COBS

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


# Packets

@dataclass(frozen=True)
class Packet:
    """One packet: ``type`` (a :class:`PacketType`, or an int for unknown types), ``seq``,
    ``payload``."""
    type: object
    seq: int
    payload: bytes = b""


def _header_bytes(type, seq, length):
    return pack(Header, type=type, seq=seq, length=length)


def encode_packet(type, seq, payload=b""):
    """Packet bytes (header, payload, CRC), before COBS encoding."""
    payload = bytes(payload)
    if len(payload) > MAX_PAYLOAD:
        raise ValueError(f"Payload of {len(payload)} bytes is longer than the maximum of "
                         f"{MAX_PAYLOAD} bytes")
    if not 0 <= seq < 256:
        raise ValueError(f"Sequence number must be from 0 to 255, not {seq!r}")
    body = _header_bytes(type, seq, len(payload)) + payload
    return body + crc16(body).to_bytes(CRC_BYTES, "big")


def encode_frame(type, seq, payload=b""):
    """A packet as it goes on the wire: COBS-encoded packet bytes, then the delimiter."""
    return cobs_encode(encode_packet(type, seq, payload)) + bytes([DELIMITER])


def packet_type(value):
    """``value`` as a :class:`PacketType`, or the number itself for an unknown type."""
    try:
        return PacketType(value)
    except ValueError:
        return value


def decode_packet(packet):
    """Check packet bytes (after COBS decoding); returns ``(Packet, None)`` or ``(None, code)``.

    The checks, in order: too long (``OVERSIZE``), shorter than header and CRC (``TRUNCATED``),
    CRC (``BAD_CRC``), header length against payload length (``BAD_LENGTH``).
    """
    if len(packet) > MAX_PACKET:
        return None, NakCode.OVERSIZE
    if len(packet) < HEADER_BYTES + CRC_BYTES:
        return None, NakCode.TRUNCATED
    if crc16(packet) != 0:
        return None, NakCode.BAD_CRC
    header = unpack_from(Header, packet)
    type, seq, length = header["type"], header["seq"], header["length"]
    payload = packet[HEADER_BYTES:-CRC_BYTES]
    if length != len(payload):
        return None, NakCode.BAD_LENGTH
    return Packet(packet_type(type), seq, bytes(payload)), None


def decode_frame(frame):
    """Check and decode one frame as received (COBS-encoded, without its delimiter); returns
    ``(Packet, None)`` or ``(None, code)``.

    The checks, in order: more than :data:`MAX_ENCODED` bytes (``OVERSIZE``), a COBS block cut
    by the delimiter (``TRUNCATED``), then those of :func:`decode_packet`.
    """
    if len(frame) > MAX_ENCODED:
        return None, NakCode.OVERSIZE
    try:
        packet_bytes = cobs_decode(frame)
    except CobsError:
        return None, NakCode.TRUNCATED
    return decode_packet(packet_bytes)


# Streaming decoder

@dataclass(frozen=True)
class LinkError:
    """A frame dropped: ``code`` (a link :class:`NakCode`) and the ``frame`` bytes as received
    (COBS-encoded, without the delimiter)."""
    code: NakCode
    frame: bytes


@dataclass(frozen=True)
class SequenceGap:
    """Packets missing before ``packet``: ``expected`` sequence number, ``received`` one,
    ``missing`` packets (modulo 256)."""
    expected: int
    received: int
    missing: int


@dataclass(frozen=True)
class Resync:
    """Bytes skipped before the first delimiter seen (the decoder started mid-frame)."""
    skipped: int


@dataclass
class LinkCounters:
    """What a :class:`FrameDecoder` has seen. ``errors`` maps each link :class:`NakCode` to the
    number of frames dropped for it."""
    bytes: int = 0
    packets: int = 0
    payload_bytes: int = 0
    errors: dict = field(default_factory=lambda: dict.fromkeys(LINK_COUNTERS, 0))
    sequence_gaps: int = 0
    missing_packets: int = 0
    resyncs: int = 0
    skipped_bytes: int = 0

    @property
    def dropped_frames(self):
        return sum(self.errors.values())


class FrameDecoder:
    """Streaming frame decoder.

    Feed it bytes as they arrive with :meth:`feed`; it returns, in order, every :class:`Packet`
    decoded and a :class:`LinkError`, :class:`SequenceGap` or :class:`Resync` for everything
    that went wrong. :attr:`counters` (:class:`LinkCounters`) adds everything up.

    A lone delimiter (an empty frame) is ignored: a sender may put delimiters between frames to
    flush a receiver. The checks and their order are those of the gateware decoder: more than
    :data:`MAX_ENCODED` bytes (``OVERSIZE``; the excess is not even kept, so random input cannot
    make the decoder grow), a COBS block cut by the delimiter (``TRUNCATED``), then
    :func:`decode_packet`.

    Parameters
    ----------
    synced : bool
        ``False`` (default) when the decoder may start in the middle of a frame, as when a host
        opens a port to a running device: bytes up to the first delimiter are skipped and
        reported as a :class:`Resync`. ``True`` when the first byte starts a frame.
    """

    _KEEP = MAX_ENCODED

    def __init__(self, *, synced=False):
        self.counters = LinkCounters()
        self._synced = bool(synced)
        self._frame = bytearray()
        self._length = 0
        self._expected_seq = None

    def feed(self, data):
        """Decode ``data`` (bytes-like); returns the list of packets and reports found."""
        out = []
        data = bytes(data)
        self.counters.bytes += len(data)
        start = 0
        while start < len(data):
            end = data.find(DELIMITER, start)
            chunk = data[start:] if end < 0 else data[start:end]
            self._length += len(chunk)
            room = self._KEEP + 1 - len(self._frame)
            if room > 0:
                self._frame += chunk[:room]
            if end < 0:
                break
            self._end_frame(out)
            start = end + 1
        return out

    def _end_frame(self, out):
        frame, length = bytes(self._frame), self._length
        self._frame.clear()
        self._length = 0
        if not self._synced:
            self._synced = True
            if length:
                self.counters.resyncs += 1
                self.counters.skipped_bytes += length
                out.append(Resync(length))
            return
        if length == 0:
            return
        packet, code = decode_frame(frame)
        if packet is None:
            self._drop(out, code, frame)
            return
        if self._expected_seq is not None and packet.seq != self._expected_seq:
            missing = (packet.seq - self._expected_seq) % 256
            self.counters.sequence_gaps += 1
            self.counters.missing_packets += missing
            out.append(SequenceGap(self._expected_seq, packet.seq, missing))
        self._expected_seq = (packet.seq + 1) % 256
        self.counters.packets += 1
        self.counters.payload_bytes += len(packet.payload)
        out.append(packet)

    def _drop(self, out, code, frame):
        self.counters.errors[code] += 1
        out.append(LinkError(code, frame))


class PacketEncoder:
    """Numbers the packets a host sends: ``seq`` 0, 1, 2, … modulo 256."""

    def __init__(self, seq=0):
        self.seq = seq

    def frame(self, type, payload=b""):
        """The next frame of ``type`` with ``payload``, as wire bytes."""
        frame = encode_frame(type, self.seq, payload)
        self.seq = (self.seq + 1) % 256
        return frame



# Event batches

def pack_events(events):
    """Payload of an EVENTS packet from an ``EVENT_DTYPE`` array."""
    words = _event.pack(events)
    return b"".join(int(word).to_bytes(EVENT_BYTES, "little") for word in words)


def unpack_events(payload):
    """``EVENT_DTYPE`` array from the payload of an EVENTS packet."""
    payload = bytes(payload)
    if len(payload) % EVENT_BYTES:
        raise ValueError(f"Event payload of {len(payload)} bytes is not a whole number of "
                         f"{EVENT_BYTES}-byte events")
    words = np.array([int.from_bytes(payload[i:i + EVENT_BYTES], "little")
                      for i in range(0, len(payload), EVENT_BYTES)], dtype=np.uint64)
    return _event.unpack(words)
