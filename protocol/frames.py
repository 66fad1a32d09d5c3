"""Frames of the FLISS link (``docs/protocol.md``): packets to wire frames and back.

* :func:`encode_packet` / :func:`encode_frame`: a packet as packet bytes (header, payload, CRC) /
  as a wire frame (COBS, delimiter); :class:`PacketEncoder` numbers the packets a host sends;
  :func:`decode_frame` checks one frame;
* :class:`FrameDecoder`: a streaming decoder fed with bytes as they arrive, which yields packets
  and reports every damaged frame, sequence gap and resynchronisation, and counts them.

:mod:`fliss.host.bulk` decodes large reads and recordings with numpy, with the same results. The
gateware (:mod:`fliss.hdl.link.framing`) is tested against this module bit for bit.
"""

from dataclasses import dataclass, field

from ..hdl.protocol import (DELIMITER, CRC_BYTES, PacketType, Header, HEADER_BYTES, MAX_PAYLOAD,
                            MAX_PACKET, MAX_ENCODED, NakCode, LINK_COUNTERS)
from .cobs import CobsError, cobs_decode, cobs_encode
from .crc import crc16
from .layout import pack, unpack_from


__all__ = ["packet_type", "Packet", "encode_packet", "encode_frame", "decode_packet",
           "decode_frame", "LinkError", "SequenceGap", "Resync", "LinkCounters", "FrameDecoder",
           "PacketEncoder"]


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
