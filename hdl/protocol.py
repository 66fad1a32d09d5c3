"""The FLISS link protocol: the one definition of packet types, header, CRC, limits and NAK codes.

Gateware (:mod:`fliss.hdl.framing`, :mod:`fliss.hdl.command`, :mod:`fliss.hdl.packetizer`), the
software codec (:mod:`fliss.sim.codec`), the models, the testbenches and the host all import
these names; no number of the protocol is written anywhere else. Every payload is an
:mod:`amaranth.lib.data` layout here, and software packs and unpacks payloads from these layouts
(:func:`fliss.sim.codec.pack`, :func:`fliss.sim.codec.unpack`). ``docs/protocol.md`` describes
the byte layouts, and a test holds it to these definitions.

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
    "PROTOCOL_VERSION", "GATEWARE_VERSION", "version_numbers", "GATEWARE_MAJOR", "GATEWARE_MINOR",
    "DEFAULT_BAUD", "DELIMITER", "COBS_MAX_RUN",
    "CRC_WIDTH", "CRC_POLY", "CRC_INIT", "CRC_CHECK", "CRC_BYTES",
    "PacketType", "Header", "HEADER_BYTES", "MAX_PAYLOAD", "MAX_PACKET", "MAX_ENCODED",
    "MAX_FRAME", "NakCode", "Ack", "Nak", "Identity", "ReadRequest", "REGISTER_BITS",
    "REGISTER_BYTES", "registers_layout", "READ_MAX", "CONSISTENCY", "COUNTER_BITS", "Status",
    "STATUS_FIELDS", "LINK_COUNTERS", "LINK_FIELDS", "LINK_ERRORS", "HistogramChunk",
    "HISTOGRAM_COUNT_BITS", "CHUNK_BINS",
    "EVENT_BYTES", "MAX_EVENTS_PER_PACKET", "DIRECTION_BIT",
]


#: Version of this protocol, reported in the identity packet.
PROTOCOL_VERSION = 2

#: Version of the gateware (the package's version in ``pyproject.toml``; a test holds the two
#: together). The identity packet reports its major and minor numbers.
GATEWARE_VERSION = "0.1.0"


def version_numbers(text):
    """``(major, minor)`` of a version string such as ``"0.1.0"``, each as a byte; a part that
    is not a number counts as 0."""
    parts = [int(part) if part.isdigit() else 0 for part in text.split(".")[:2]] + [0, 0]
    return parts[0] & 0xff, parts[1] & 0xff


#: Major and minor number of :data:`GATEWARE_VERSION`, as the identity packet reports them.
GATEWARE_MAJOR, GATEWARE_MINOR = version_numbers(GATEWARE_VERSION)

#: Default baud rate of the link, gateware and host: what an FT2232H bridge (iCEBreaker, many
#: ULX3S) carries reliably.
DEFAULT_BAUD = 3_000_000

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
    #: Read registers: payload :class:`ReadRequest`; answered with REGISTERS.
    READ      = 0x03
    #: Write registers: payload :func:`registers_layout`; answered with ACK.
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
    #: Identity: payload :class:`Identity`.
    IDENTITY  = 0x82
    #: Register values: payload :func:`registers_layout`.
    REGISTERS = 0x83
    #: Status with counters: payload :class:`Status`.
    STATUS    = 0x84
    #: Raw event batch: a whole number of :data:`EVENT_BYTES`-byte :class:`Event` values.
    EVENTS    = 0x85
    #: Histogram chunk: a :class:`HistogramChunk`, then up to :data:`CHUNK_BINS` counts.
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


class Identity(data.Struct):
    """Payload of an IDENTITY packet: protocol version, gateware version, number of registers,
    clock frequency in Hz and baud rate of the board."""
    protocol:       8
    gateware_major: 8
    gateware_minor: 8
    registers:      8
    clock_hz:       32
    baud:           32


class ReadRequest(data.Struct):
    """Payload of a READ command: the first register's ``address`` and the ``count`` of
    registers to read (1 to :data:`READ_MAX`)."""
    address: 16
    count:   8


#: Width of a register value on the wire, in bits.
REGISTER_BITS = 32
#: Bytes of a register value on the wire.
REGISTER_BYTES = REGISTER_BITS // 8


def registers_layout(count):
    """Layout of a WRITE command's and a REGISTERS reply's payload with ``count`` registers:
    the first register's ``address`` (u16), then ``values``, one u32 per register."""
    return data.StructLayout({
        "address": 16,
        "values":  data.ArrayLayout(REGISTER_BITS, count),
    })


#: Most registers in one READ (the REGISTERS reply carries the address and one u32 each).
READ_MAX = (MAX_PAYLOAD * 8 - registers_layout(0).size) // REGISTER_BITS

#: ``detail`` of a NAK ``OUT_OF_RANGE`` refused for inconsistent settings rather than for one
#: register out of its range (whose address is the detail then).
CONSISTENCY = 0xffff

#: Width of every error and traffic counter, in bits.
COUNTER_BITS = 32


class Status(data.Struct):
    """Payload of a STATUS packet: the board's counters, in this order, each a u32 that starts
    at zero after reset and saturates at ``2**32 - 1``."""
    running:             COUNTER_BITS   # 1 while acquiring
    pulses:              COUNTER_BITS   # victim laser pulses since the start
    frames:              COUNTER_BITS   # histograms completed
    events:              COUNTER_BITS   # events accepted from the TDC
    dropped_stopped:     COUNTER_BITS   # events while stopped
    dropped_gate:        COUNTER_BITS   # events outside the gate
    dropped_overflow:    COUNTER_BITS   # coarse TDC: photon beyond the timestamp range
    dropped_overrun:     COUNTER_BITS   # events faster than the interface can take
    dropped_fifo:        COUNTER_BITS   # raw mode: events dropped at the full FIFO
    dropped_histogram:   COUNTER_BITS   # histogram mode: events while no frame was filling
    histogram_overflow:  COUNTER_BITS   # histogram mode: events beyond the last bin
    uart_framing_errors: COUNTER_BITS   # bytes with a bad stop bit
    uart_overruns:       COUNTER_BITS   # bytes lost because the receiver was full
    bad_crc:             COUNTER_BITS   # frames dropped: bad CRC
    truncated:           COUNTER_BITS   # frames dropped: truncated
    oversize:            COUNTER_BITS   # frames dropped: oversize
    bad_length:          COUNTER_BITS   # frames dropped: header length wrong
    commands:            COUNTER_BITS   # commands received
    refused:             COUNTER_BITS   # commands refused with a NAK


#: Names of the :class:`Status` counters, in payload order.
STATUS_FIELDS = tuple(name for name, _ in data.Layout.cast(Status))

#: The link errors a frame decoder finds, each with the :class:`Status` counter that counts it
#: (and the frame decoders' tally of it).
LINK_COUNTERS = {
    NakCode.BAD_CRC:    "bad_crc",
    NakCode.TRUNCATED:  "truncated",
    NakCode.OVERSIZE:   "oversize",
    NakCode.BAD_LENGTH: "bad_length",
}

#: The :class:`Status` counters of :data:`LINK_COUNTERS`, in :class:`NakCode` order.
LINK_FIELDS = tuple(LINK_COUNTERS.values())

#: NAK codes that report a damaged frame rather than refuse a command: the frame decoder's and
#: the UART receiver's. A host re-sends the command at once.
LINK_ERRORS = frozenset(LINK_COUNTERS) | {NakCode.UART_FRAMING}


class HistogramChunk(data.Struct):
    """Start of a HISTOGRAM payload; up to :data:`CHUNK_BINS` counts of
    :data:`HISTOGRAM_COUNT_BITS` bits follow, in bin order."""
    frame:     32   # histogram number since reset
    first_bin: 16   # bin of the first count in this chunk
    shift:     8    # bins are 2**shift timestamp codes wide
    last:      8    # 1 in the last chunk of a frame


#: Width of each bin count in a HISTOGRAM payload, in bits (little-endian words).
HISTOGRAM_COUNT_BITS = 16

#: Most bins in one HISTOGRAM chunk.
CHUNK_BINS = 128


assert (data.Layout.cast(HistogramChunk).size + CHUNK_BINS * HISTOGRAM_COUNT_BITS) // 8 \
    <= MAX_PAYLOAD

#: Bytes per event in an EVENTS packet: the :class:`~fliss.hdl.event.Event` struct, as a
#: little-endian integer, padded to whole bytes.
EVENT_BYTES = (data.Layout.cast(Event).size + 7) // 8

#: Most events in one EVENTS packet.
MAX_EVENTS_PER_PACKET = MAX_PAYLOAD // EVENT_BYTES
