"""The FLISS link protocol: the one definition of packet types, header, CRC, limits and NAK codes.

Gateware (:mod:`fliss.hdl.framing`), testbenches and the host codec (:mod:`fliss.host.protocol`)
all import these names; no number of the protocol is written anywhere else. ``docs/protocol.md``
describes the byte layouts.

A *packet* is a :class:`Header` (type, sequence number, payload length), a payload of at most
:data:`MAX_PAYLOAD` bytes and a CRC-16. On the wire a packet becomes a *frame*: the packet bytes
are COBS-encoded (so they contain no zero byte) and followed by one :data:`DELIMITER` (zero) byte.

Byte order: the header is the little-endian image of the :class:`Header` struct (its first field
in the first byte); multi-byte payload fields are little-endian. The CRC is sent most significant
byte first, so that the CRC of a whole packet, CRC included, is zero.
"""

from amaranth.lib import data, enum

from .event import Event


__all__ = [
    "PROTOCOL_VERSION", "DELIMITER", "COBS_MAX_RUN",
    "CRC_WIDTH", "CRC_POLY", "CRC_INIT", "CRC_CHECK", "CRC_BYTES",
    "PacketType", "Header", "HEADER_BYTES", "MAX_PAYLOAD", "MAX_PACKET", "MAX_ENCODED",
    "MAX_FRAME", "NakCode", "Ack", "Nak", "COUNTER_BITS", "EVENT_BYTES", "MAX_EVENTS_PER_PACKET",
    "DIRECTION_BIT",
]


#: Version of this protocol, reported in the identity packet.
PROTOCOL_VERSION = 1

#: Frame delimiter. COBS removes every zero byte from the packet, so a zero always ends a frame.
DELIMITER = 0x00

#: Longest run of non-zero bytes in one COBS block (code byte ``0xff``).
COBS_MAX_RUN = 254

#: CRC-16/IBM-3740 (also called CRC-16/CCITT-FALSE): polynomial ``x^16 + x^12 + x^5 + 1``,
#: initial value ``0xffff``, bits processed most significant first, no final XOR. Python's
#: :func:`binascii.crc_hqx` with ``0xffff`` as initial value computes the same CRC.
CRC_WIDTH = 16
CRC_POLY  = 0x1021
CRC_INIT  = 0xffff
#: CRC of the ASCII bytes ``123456789`` (the catalogue check value of CRC-16/IBM-3740).
CRC_CHECK = 0x29b1
#: Bytes of CRC at the end of each packet.
CRC_BYTES = CRC_WIDTH // 8

#: Packet types with this bit set travel from the device to the host.
DIRECTION_BIT = 0x80


class PacketType(enum.Enum, shape=8):
    """Packet types. Host to device below :data:`DIRECTION_BIT`, device to host above."""
    # Commands, host to device. The device answers each one with ACK, NAK or a data packet.
    #: No operation; answered with ACK. Use to test the link.
    PING      = 0x01
    #: Ask for the IDENTITY packet.
    IDENTIFY  = 0x02
    #: Read registers: payload ``address`` (u16), ``count`` (u8); answered with REGISTERS.
    READ      = 0x03
    #: Write registers: payload ``address`` (u16), then one u32 per register; answered with ACK.
    WRITE     = 0x04
    #: Start acquisition; answered with ACK.
    START     = 0x05
    #: Stop acquisition; answered with ACK.
    STOP      = 0x06
    #: Ask for a STATUS packet.
    GET_STATUS = 0x07

    # Replies and data, device to host.
    #: Command accepted: payload :class:`Ack`.
    ACK       = 0x80
    #: Command refused: payload :class:`Nak`.
    NAK       = 0x81
    #: Identity: protocol version, gateware version, clock frequency.
    IDENTITY  = 0x82
    #: Register values: payload ``address`` (u16), then one u32 per register.
    REGISTERS = 0x83
    #: Status with counters (events, dropped events, UART errors, bad CRCs, refused commands).
    STATUS    = 0x84
    #: Raw event batch: a whole number of :data:`EVENT_BYTES`-byte events.
    EVENTS    = 0x85
    #: Histogram chunk.
    HISTOGRAM = 0x86


class Header(data.Struct):
    """Packet header, the first :data:`HEADER_BYTES` bytes of every packet (little-endian).

    ``seq`` counts packets in each direction separately, modulo 256: each side numbers the
    packets it sends 0, 1, 2, … so that the receiver sees a gap when a packet is lost.
    ``length`` is the number of payload bytes, at most :data:`MAX_PAYLOAD`.
    """
    type:   8
    seq:    8
    length: 16


#: Bytes in the header.
HEADER_BYTES = data.Layout.cast(Header).size // 8

#: Largest payload, in bytes: a histogram chunk of 128 16-bit bins or 64 32-bit bins (plus a
#: few bytes of position) fits; a receiver needs a buffer of this size.
MAX_PAYLOAD = 264

#: Largest packet (header, payload, CRC), in bytes, before COBS encoding.
MAX_PACKET = HEADER_BYTES + MAX_PAYLOAD + CRC_BYTES

#: Largest COBS-encoded packet, in bytes: COBS adds a code byte in front of every run of up to
#: :data:`COBS_MAX_RUN` bytes. A receiver drops longer frames as ``OVERSIZE``.
MAX_ENCODED = MAX_PACKET + 1 + (MAX_PACKET - 1) // COBS_MAX_RUN

#: Largest frame on the wire, in bytes: the encoded packet and the delimiter.
MAX_FRAME = MAX_ENCODED + 1


class NakCode(enum.Enum, shape=8):
    """Reason for refusing a frame or a command: the ``code`` of a :class:`Nak`.

    The first five are found by the frame decoder (link errors); the others by the command
    processor. A refused command changes nothing.
    """
    #: The CRC does not match: the frame was damaged.
    BAD_CRC      = 0x01
    #: A delimiter arrived inside a COBS block, or the frame is shorter than header and CRC.
    TRUNCATED    = 0x02
    #: More than :data:`MAX_ENCODED` bytes before the delimiter, or more than
    #: :data:`MAX_PACKET` bytes once decoded.
    OVERSIZE     = 0x03
    #: The CRC matches but the header's ``length`` does not match the payload received.
    BAD_LENGTH   = 0x04
    #: A byte arrived with a bad stop bit (UART framing error).
    UART_FRAMING = 0x05
    #: Unknown or device-to-host packet type.
    UNKNOWN_TYPE = 0x10
    #: Payload length wrong for the command.
    BAD_PAYLOAD  = 0x11
    #: No such register, or a read-only register written.
    BAD_ADDRESS  = 0x12
    #: Value out of range (L above 32, Wm above 16, a period not above the pulse, a zero seed…).
    OUT_OF_RANGE = 0x13
    #: Not possible in the current state (for example a setting that cannot change while running).
    BUSY         = 0x14


class Ack(data.Struct):
    """Payload of an ACK packet: the sequence number of the accepted command."""
    seq: 8


class Nak(data.Struct):
    """Payload of a NAK packet.

    ``seq`` is the sequence number of the refused command as received (meaningless for the link
    errors, whose header cannot be trusted); ``code`` a :class:`NakCode`; ``detail`` a
    code-dependent value, such as the register address refused.
    """
    seq:    8
    code:   NakCode
    detail: 16


#: Width of every error and traffic counter, in bits.
COUNTER_BITS = 32

#: Bytes per event in an EVENTS packet: the :class:`~fliss.hdl.event.Event` struct, as a
#: little-endian integer, padded to whole bytes.
EVENT_BYTES = (data.Layout.cast(Event).size + 7) // 8

#: Most events in one EVENTS packet.
MAX_EVENTS_PER_PACKET = MAX_PAYLOAD // EVENT_BYTES
