"""The FLISS link protocol: the one definition of packet types, header, CRC, limits and NAK codes.

Gateware (:mod:`fliss.hdl.link.framing`, :mod:`fliss.hdl.link.command`, :mod:`fliss.hdl.packets`), the
software codec (:mod:`fliss.protocol`), the models, the testbenches and the host all import
these names; no number of the protocol is written anywhere else. Every payload is an
:mod:`amaranth.lib.data` layout here, and software packs and unpacks payloads from these layouts
(:func:`fliss.protocol.pack`, :func:`fliss.protocol.unpack`). ``docs/protocol.md`` describes
the byte layouts, and a test holds it to these definitions.

A *packet* is a :class:`Header` (type, sequence number, payload length), a payload of at most
:data:`MAX_PAYLOAD` bytes and a CRC-16. On the wire a packet becomes a *frame*: the packet bytes
are COBS-encoded (so they contain no zero byte) and followed by one :data:`DELIMITER` (zero) byte.

Byte order: the header is the little-endian image of the :class:`Header` struct (its first field
in the first byte); multi-byte payload fields are little-endian. The CRC is sent most significant
byte first, so that the CRC of a whole packet, CRC included, is zero.
"""

from amaranth.lib import data, enum

from .. import __version__
from .event import Event


__all__ = [
    "PROTOCOL_VERSION", "GATEWARE_VERSION", "version_numbers", "GATEWARE_MAJOR", "GATEWARE_MINOR",
    "GATEWARE_PATCH",
    "DEFAULT_BAUD", "DELIMITER", "COBS_MAX_RUN",
    "CRC_WIDTH", "CRC_POLY", "CRC_INIT", "CRC_CHECK", "CRC_BYTES",
    "PacketType", "AcquisitionMode", "DATA_PACKETS", "Header", "HEADER_BYTES", "MAX_PAYLOAD", "MAX_PACKET", "MAX_ENCODED",
    "NakCode", "Ack", "Nak", "Identity", "ReadRequest", "REGISTER_BITS",
    "REGISTER_BYTES", "registers_layout", "READ_MAX", "CONSISTENCY", "COUNTER_BITS", "Status",
    "STATUS_FIELDS", "LINK_COUNTERS", "LINK_FIELDS", "LINK_ERRORS", "HistogramChunk",
    "HISTOGRAM_COUNT_BITS", "CHUNK_BINS", "HistogramCompact", "COMPACT_BYTES",
    "MAX_FRAME_BITS", "DepthHeader", "DepthRecord", "DEPTH_HEADER_BYTES",
    "DEPTH_RECORD_BYTES", "DEPTH_PIXELS", "DEPTH_FRACTION_BITS", "DEPTH_BACKGROUND_FRACTION_BITS",
    "EVENT_BYTES", "MAX_EVENTS_PER_PACKET", "DIRECTION_BIT",
]


#: Version of this protocol, reported in the identity packet.
PROTOCOL_VERSION = 5

#: Version of the gateware: the package's version (:data:`fliss.__version__`, written there
#: only). The identity packet reports its major, minor and patch numbers.
GATEWARE_VERSION = __version__


def version_numbers(text):
    """``(major, minor, patch)`` of a version string such as ``"0.2.0"``, each as a byte; a
    part that is missing or not a number (``"0.2.0rc1"``: ``rc1``) counts as 0."""
    parts = [int(part) if part.isdigit() else 0 for part in text.split(".")[:3]]
    parts += [0] * (3 - len(parts))
    return tuple(part & 0xff for part in parts)


#: Major, minor and patch number of :data:`GATEWARE_VERSION`, as the identity packet reports them.
GATEWARE_MAJOR, GATEWARE_MINOR, GATEWARE_PATCH = version_numbers(GATEWARE_VERSION)

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
    #: Depth frame: a :class:`DepthHeader`, then one :class:`DepthRecord` per pixel.
    DEPTH     = 0x87
    #: Compact histogram chunk: a :class:`HistogramCompact`, then up to :data:`COMPACT_BYTES`
    #: bytes of tokens (runs of empty bins and counts, see :class:`HistogramCompact`).
    HISTOGRAM_COMPACT = 0x88


class AcquisitionMode(enum.Enum, shape=2):
    """What the board sends while acquiring (the ``acquisition`` register): its data packets
    are :data:`DATA_PACKETS`'s of the same kind."""
    #: Histograms, one per integration time (per pixel: see ``pixel_bits``).
    HISTOGRAM = 0
    #: Every event, as EVENTS packets.
    RAW       = 1
    #: Depth frames: per pixel, the position, height and background of its strongest peak,
    #: one DEPTH packet per integration time.
    DEPTH     = 2


#: The packets a board sends unasked while it acquires, and the kind of data each carries; every
#: other device-to-host packet is a reply to a command. The software's list of data packets
#: (:mod:`fliss.protocol.packets`) is made from this one.
DATA_PACKETS = {
    PacketType.EVENTS: "events",
    PacketType.HISTOGRAM: "histogram",
    PacketType.HISTOGRAM_COMPACT: "histogram",
    PacketType.DEPTH: "depth",
}


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

#: Most pixels in a frame (the sensor's 6-bit pixel address), and so in one DEPTH packet.
DEPTH_PIXELS = 64

#: Fraction bits of a :class:`DepthRecord` ``position`` (1/16 bin).
DEPTH_FRACTION_BITS = 4
#: Fraction bits of a :class:`DepthRecord` ``background`` (1/16 count per bin).
DEPTH_BACKGROUND_FRACTION_BITS = 4


class DepthHeader(data.Struct):
    """Start of a DEPTH payload (one per frame); ``2**pixel_bits`` :class:`DepthRecord` values
    follow, pixel ``first_pixel`` first."""
    frame:       32   # depth frame number since reset
    first_pixel: 8    # sensor address of the first pixel
    pixel_bits:  8    # the frame holds 2**pixel_bits pixels
    shift:       8    # bins are 2**shift timestamp codes wide; 2**(13 - shift) bins per pixel
    filter:      8    # matched filter width W in bins, as set (the engine uses min(W, bins))
    threshold:   16   # least height for ``detected``, in counts


class DepthRecord(data.Struct):
    """One pixel of a DEPTH payload: 56 bits, 7 bytes (little-endian, first field lowest).

    ``position`` is the peak's centre in 1/16 bin (:data:`DEPTH_FRACTION_BITS`) from the start
    of the pixel's bin 0 (bin ``j`` spans ``16 j … 16 j + 16``); ``height`` the filtered peak
    above background, in counts (sum over the filter window less ``W`` times the background,
    rounded down, at least 0); ``background`` the mean count per bin outside the peak window, in
    1/16 count (:data:`DEPTH_BACKGROUND_FRACTION_BITS`), rounded down, saturating at
    ``2**18 - 1``; ``detected`` is 1 when ``height`` reaches the frame's ``threshold``
    (``docs/depth.md``).
    """
    position:   17
    detected:   1
    height:     20
    background: 18


#: Bytes of a :class:`DepthHeader` and of a :class:`DepthRecord`.
DEPTH_HEADER_BYTES = data.Layout.cast(DepthHeader).size // 8
DEPTH_RECORD_BYTES = data.Layout.cast(DepthRecord).size // 8

#: Largest payload, in bytes: a DEPTH packet of :data:`DEPTH_PIXELS` pixels (458 bytes); a
#: histogram chunk of 128 16-bit bins fits too. A receiver needs a buffer of this size (one
#: 512-byte block RAM in the gateware's frame decoder).
MAX_PAYLOAD = DEPTH_HEADER_BYTES + DEPTH_PIXELS * DEPTH_RECORD_BYTES

#: Largest packet (header, payload, CRC), in bytes, before COBS encoding.
MAX_PACKET = HEADER_BYTES + MAX_PAYLOAD + CRC_BYTES

#: Largest COBS-encoded packet, in bytes: COBS adds a code byte in front of every run of up to
#: :data:`COBS_MAX_RUN` bytes. A receiver drops longer frames as ``OVERSIZE``.
MAX_ENCODED = MAX_PACKET + 1 + (MAX_PACKET - 1) // COBS_MAX_RUN


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
    clock frequency in Hz and baud rate of the board, and the width of its histogram bank's
    address, ``bank_bits``: a bank holds ``2**bank_bits`` bins, and a pixel split fits it when
    ``pixel_bits + 13 - bin_shift <= bank_bits`` (:func:`fliss.hdl.registers.split_problems`)."""
    protocol:       8
    gateware_major: 8
    gateware_minor: 8
    gateware_patch: 8
    registers:      8
    clock_hz:       32
    baud:           32
    bank_bits:      8


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
    at zero after reset and saturates at ``2**32 - 1``; and three fields that are not counts:
    ``running``, ``pulses`` (of the run) and ``ivs_used_up`` (a level: the victim's keyed
    source gives no delay, so no pulse fires in ``keyed`` mode, until a key is written)."""
    running:             COUNTER_BITS   # 1 while acquiring
    pulses:              COUNTER_BITS   # victim laser pulses since the start
    frames:              COUNTER_BITS   # histograms completed
    events:              COUNTER_BITS   # events accepted from the TDC
    dropped_stopped:     COUNTER_BITS   # events while stopped
    dropped_gate:        COUNTER_BITS   # events outside the gate
    dropped_collision:   COUNTER_BITS   # events flagged as collisions, dropped by the setting
    dropped_overflow:    COUNTER_BITS   # coarse TDC: photon beyond the timestamp range
    dropped_overrun:     COUNTER_BITS   # events faster than the interface can take
    dropped_fifo:        COUNTER_BITS   # raw mode: events dropped at the full FIFO
    dropped_histogram:   COUNTER_BITS   # histogram mode: events while no frame was filling
    dropped_pixel:       COUNTER_BITS   # histogram mode: events of an address outside the frame
    histogram_overflow:  COUNTER_BITS   # histogram mode: events beyond the last bin
    uart_framing_errors: COUNTER_BITS   # bytes with a bad stop bit
    uart_overruns:       COUNTER_BITS   # bytes lost because the receiver was full
    bad_crc:             COUNTER_BITS   # frames dropped: bad CRC
    truncated:           COUNTER_BITS   # frames dropped: truncated
    oversize:            COUNTER_BITS   # frames dropped: oversize
    bad_length:          COUNTER_BITS   # frames dropped: header length wrong
    commands:            COUNTER_BITS   # commands received
    refused:             COUNTER_BITS   # commands refused with a NAK
    ivs_used_up:         COUNTER_BITS   # 1 while the keyed source has used every IV under its key


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
    :data:`HISTOGRAM_COUNT_BITS` bits follow, in bin order.

    A frame holds ``2**pixel_bits`` pixels (addresses ``first_pixel …``) of ``2**(13 - shift)``
    bins each; its bins are numbered by the flat index ``pixel << (13 - shift) | bin``, and
    ``first_bin`` is the flat index of the chunk's first count.
    """
    frame:       32   # histogram number since reset
    first_bin:   16   # flat index of the first count in this chunk
    first_pixel: 8    # address of the frame's pixel 0
    shift:       4    # bins are 2**shift timestamp codes wide
    pixel_bits:  3    # the frame holds 2**pixel_bits pixels
    last:        1    # 1 in the last chunk of a frame


class HistogramCompact(data.Struct):
    """Start of a HISTOGRAM_COMPACT payload: the chunk covers the flat indices ``first_bin`` to
    ``last_bin`` (both included) of its frame; fields otherwise as in :class:`HistogramChunk`.

    Up to :data:`COMPACT_BYTES` bytes of *tokens* follow. A token is an unsigned LEB128 number
    ``v`` (7 bits a byte, least significant group first, bit 7 set in every byte but the
    last; at most 3 bytes): an even ``v = 2 c`` (``c`` from 1 to 65535) is one bin of count
    ``c``; an odd ``v = 2 r + 1`` (``r`` from 1 to 65535) is ``r`` empty bins. Tokens fill the
    chunk's bins from ``first_bin`` on; bins after the last token up to ``last_bin`` are empty.
    """
    frame:       32
    first_bin:   16
    last_bin:    16
    first_pixel: 8
    shift:       4
    pixel_bits:  3
    last:        1


#: Width of each bin count in a HISTOGRAM payload, in bits (little-endian words).
HISTOGRAM_COUNT_BITS = 16

#: Most bins in one HISTOGRAM chunk.
CHUNK_BINS = 128

#: A frame holds at most ``2**MAX_FRAME_BITS`` bins: flat indices are 16 bits.
MAX_FRAME_BITS = 16


assert (data.Layout.cast(HistogramChunk).size + CHUNK_BINS * HISTOGRAM_COUNT_BITS) // 8 \
    <= MAX_PAYLOAD

#: Most token bytes in one HISTOGRAM_COMPACT chunk: a full compact chunk is as long as a full
#: HISTOGRAM chunk of :data:`CHUNK_BINS` bins.
COMPACT_BYTES = (data.Layout.cast(HistogramChunk).size - data.Layout.cast(HistogramCompact).size
                 + CHUNK_BINS * HISTOGRAM_COUNT_BITS) // 8

assert data.Layout.cast(HistogramCompact).size // 8 + COMPACT_BYTES <= MAX_PAYLOAD

#: Bytes per event in an EVENTS packet: the :class:`~fliss.hdl.event.Event` struct, as a
#: little-endian integer, padded to whole bytes.
EVENT_BYTES = (data.Layout.cast(Event).size + 7) // 8

#: Most events in one EVENTS packet.
MAX_EVENTS_PER_PACKET = MAX_PAYLOAD // EVENT_BYTES
