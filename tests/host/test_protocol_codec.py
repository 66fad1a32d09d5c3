"""Software codec of the link protocol (fliss.protocol), against independent references."""

import binascii
import random

import numpy as np
import pytest

from amaranth.hdl import Shape
from amaranth.lib import data

from fliss.hdl.protocol import (PacketType, NakCode, Header, HEADER_BYTES, MAX_PAYLOAD, MAX_PACKET,
                                MAX_ENCODED, CRC_BYTES, CRC_CHECK, CRC_INIT, DIRECTION_BIT,
                                EVENT_BYTES, MAX_EVENTS_PER_PACKET, Ack, Nak, Identity, ReadRequest,
                                Status, HistogramChunk, READ_MAX, registers_layout)
from fliss import protocol
from fliss.protocol.events import EVENT_DTYPE


# Definitions

def test_layout_constants():
    assert HEADER_BYTES == 4
    assert EVENT_BYTES == 7                 # 13 + 6 + 1 + 32 = 52 bits
    assert MAX_EVENTS_PER_PACKET * EVENT_BYTES <= MAX_PAYLOAD
    assert (MAX_EVENTS_PER_PACKET + 1) * EVENT_BYTES > MAX_PAYLOAD
    assert MAX_PACKET == HEADER_BYTES + MAX_PAYLOAD + CRC_BYTES
    assert MAX_ENCODED == len(protocol.cobs_encode(b"\x01" * MAX_PACKET))


def _random_values(layout, rng):
    # Random values of every field of ``layout``, nested as pack() takes them.
    if isinstance(layout, data.StructLayout):
        return {name: _random_values(field.shape, rng) for name, field in layout}
    if isinstance(layout, data.ArrayLayout):
        return [_random_values(layout.elem_shape, rng) for _ in range(layout.length)]
    return rng.getrandbits(Shape.cast(layout).width)


@pytest.mark.parametrize("layout", [Header, Ack, Identity, ReadRequest, Status, HistogramChunk,
                                    registers_layout(1), registers_layout(READ_MAX)],
                         ids=lambda layout: getattr(layout, "__name__", "registers_layout"))
def test_pack_is_the_gateware_value(layout):
    # pack() gives the little-endian bytes of the layout's value as Amaranth builds it, and
    # unpack() gives the values back.
    rng = random.Random(7)
    cast = data.Layout.cast(layout)
    for _ in range(20):
        values = _random_values(cast, rng)
        payload = protocol.pack(layout, values)
        assert len(payload) == protocol.byte_size(layout) == cast.size // 8
        assert int.from_bytes(payload, "little") == cast.const(values).as_bits()
        assert protocol.unpack(layout, payload) == values
        assert protocol.unpack_from(layout, b"\xaa" + payload + b"\x55", 1) == values


def test_pack_nak_and_words():
    payload = protocol.pack(Nak, seq=3, code=NakCode.OUT_OF_RANGE, detail=0x0102)
    assert payload == bytes([3, NakCode.OUT_OF_RANGE.value, 0x02, 0x01])
    assert protocol.unpack(Nak, payload) == {"seq": 3, "code": NakCode.OUT_OF_RANGE.value,
                                         "detail": 0x0102}
    assert protocol.pack(Nak, code=NakCode.BAD_CRC) == bytes([0, 1, 0, 0])   # left out: zero
    assert protocol.pack_words([1, 0xffffffff]) == bytes([1, 0, 0, 0, 0xff, 0xff, 0xff, 0xff])
    assert protocol.unpack_words(bytes([9, 1, 0, 2, 0]), 16, offset=1) == [0x0001, 0x0002]


def test_pack_refuses_what_does_not_fit():
    with pytest.raises(ValueError, match=r"^payload\.seq = 256 does not fit in 8 bits$"):
        protocol.pack(Ack, seq=256)
    with pytest.raises(ValueError, match=r"^payload has no field 'sequence'$"):
        protocol.pack(Ack, sequence=1)
    with pytest.raises(ValueError, match=r"^payload\.values needs 2 elements, not 1$"):
        protocol.pack(registers_layout(2), address=0, values=[1])
    with pytest.raises(ValueError, match=r"^Payload of 3 bytes, not 4$"):
        protocol.unpack(Nak, b"abc")
    with pytest.raises(ValueError, match=r"^Words must be from 0 to 65535$"):
        protocol.pack_words([1 << 16], 16)
    with pytest.raises(ValueError, match=r"^3 bytes are not a whole number of 4-byte words$"):
        protocol.unpack_words(b"abc")


def test_packet_type_directions():
    host_to_device = {PacketType.PING, PacketType.IDENTIFY, PacketType.READ, PacketType.WRITE,
                      PacketType.START, PacketType.STOP, PacketType.GET_STATUS}
    for type in PacketType:
        assert (type.value & DIRECTION_BIT == 0) == (type in host_to_device), type


# CRC

def test_crc_check_value():
    assert protocol.crc16(b"123456789") == CRC_CHECK == 0x29b1
    assert protocol.crc16(b"") == CRC_INIT


def test_crc_against_binascii():
    rng = random.Random(1)
    for length in list(range(20)) + [100, 1000]:
        data = bytes(rng.randint(0, 255) for _ in range(length))
        assert protocol.crc16(data) == binascii.crc_hqx(data, 0xffff)
        # Continuing a CRC is the CRC of the concatenation.
        assert protocol.crc16(data[5:], protocol.crc16(data[:5])) == protocol.crc16(data)
        # With the CRC appended most significant byte first, the CRC is zero.
        assert protocol.crc16(data + protocol.crc16(data).to_bytes(2, "big")) == 0


# COBS

@pytest.mark.parametrize("data, encoded", [
    # The examples of Cheshire and Baker's COBS, as tabulated on Wikipedia.
    ("00", "0101"),
    ("0000", "010101"),
    ("00110000", "0102110101"),
    ("11220033", "0311220233"),
    ("11223344", "0511223344"),
    ("11000000", "0211010101"),
    ("", "01"),
])
def test_cobs_vectors(data, encoded):
    assert protocol.cobs_encode(bytes.fromhex(data)) == bytes.fromhex(encoded)
    assert protocol.cobs_decode(bytes.fromhex(encoded)) == bytes.fromhex(data)


def test_cobs_long_runs():
    run = bytes(range(1, 255))                           # 254 non-zero bytes
    assert protocol.cobs_encode(run) == b"\xff" + run
    assert protocol.cobs_encode(b"\x00" + run) == b"\x01\xff" + run
    assert protocol.cobs_encode(run + b"\xff") == b"\xff" + run + b"\x02\xff"
    assert protocol.cobs_encode(run + b"\x00") == b"\xff" + run + b"\x01\x01"
    assert protocol.cobs_encode(bytes(range(2, 256)) + b"\x00\x01") == (
        b"\xff" + bytes(range(2, 256)) + b"\x01\x02\x01")


def test_cobs_round_trip():
    rng = random.Random(2)
    for length in list(range(0, 12)) + [253, 254, 255, 256, 507, 508, 509, 1000]:
        for zeros in (0.0, 0.01, 0.5, 1.0):
            data = bytes(0 if rng.random() < zeros else rng.randint(1, 255)
                         for _ in range(length))
            encoded = protocol.cobs_encode(data)
            assert 0 not in encoded
            assert len(encoded) <= length + 1 + max(length - 1, 0) // 254
            assert protocol.cobs_decode(encoded) == data


@pytest.mark.parametrize("encoded, message", [
    ("0311", "block at offset 0 is cut short"),
    ("021103", "block at offset 2 is cut short"),
    ("0200", "zero byte in block at offset 0"),
    ("", "empty"),
])
def test_cobs_decode_errors(encoded, message):
    with pytest.raises(protocol.CobsError, match=f"^{message}$"):
        protocol.cobs_decode(bytes.fromhex(encoded))


# Packets

def test_packet_bytes():
    payload = b"\x00\x01\x02"
    packet = protocol.encode_packet(PacketType.WRITE, 0x2a, payload)
    body = bytes([0x04, 0x2a, 0x03, 0x00]) + payload   # type, seq, length (little-endian)
    assert packet == body + binascii.crc_hqx(body, 0xffff).to_bytes(2, "big")
    frame = protocol.encode_frame(PacketType.WRITE, 0x2a, payload)
    assert frame[-1] == 0 and 0 not in frame[:-1]
    assert protocol.cobs_decode(frame[:-1]) == packet
    long = protocol.encode_packet(PacketType.HISTOGRAM, 0, bytes(MAX_PAYLOAD))
    assert long[2:4] == MAX_PAYLOAD.to_bytes(2, "little")


def test_header_struct_layout():
    # The wire header is the little-endian image of the Header struct.
    header = Header.from_bits(int.from_bytes(bytes([0x85, 0x07, 0x34, 0x01]), "little"))
    assert (header.type, header.seq, header.length) == (0x85, 0x07, 0x134)


@pytest.mark.parametrize("kwargs, message", [
    ({"payload": bytes(MAX_PAYLOAD + 1)},
     f"Payload of {MAX_PAYLOAD + 1} bytes is longer than the maximum of {MAX_PAYLOAD} bytes"),
    ({"seq": 256}, "Sequence number must be from 0 to 255, not 256"),
    ({"seq": -1}, "Sequence number must be from 0 to 255, not -1"),
])
def test_encode_errors(kwargs, message):
    arguments = {"type": PacketType.PING, "seq": 0, "payload": b""} | kwargs
    with pytest.raises(ValueError, match=f"^{message}$"):
        protocol.encode_packet(**arguments)


# Streaming decoder

def _raw_frame(header_length, payload, seq=0, crc_xor=0):
    body = bytes([PacketType.EVENTS.value, seq]) + header_length.to_bytes(2, "little") + payload
    crc = protocol.crc16(body) ^ crc_xor
    return protocol.cobs_encode(body + crc.to_bytes(2, "big")) + b"\x00"


def test_decoder_reports_everything():
    good = [protocol.encode_frame(PacketType.EVENTS, seq, bytes([seq, 0, seq])) for seq in range(10)]
    stream = (b"\x17\x42\x99" + b"\x00"          # mid-frame start: resync, 3 bytes skipped
              + good[0] + good[1]
              + _raw_frame(3, b"\x02\x00\x02", seq=2, crc_xor=0x0100)       # bad CRC
              + good[3]                                                     # gap: 2 missing
              + good[4][:5] + b"\x00"                                       # truncated
              + b"\x00\x00"                                                 # empty frames
              + b"\x01\x01\x01\x00"                                         # too short
              + _raw_frame(MAX_PAYLOAD + 1, bytes(MAX_PAYLOAD + 1))         # oversize
              + b"\x07" * (MAX_ENCODED + 1) + b"\x00"                       # oversize
              + _raw_frame(5, b"\x01\x02\x03", seq=8)                       # bad length
              + good[5] + good[6] + good[9])                                # gap: 2 missing
    decoder = protocol.FrameDecoder()
    items = decoder.feed(stream)
    Packet, Gap, Error = protocol.Packet, protocol.SequenceGap, protocol.LinkError
    kinds = [(type(item).__name__,
              item.seq if isinstance(item, Packet) else
              (item.expected, item.missing) if isinstance(item, Gap) else
              item.code if isinstance(item, Error) else item.skipped) for item in items]
    assert kinds == [
        ("Resync", 3),
        ("Packet", 0), ("Packet", 1),
        ("LinkError", NakCode.BAD_CRC),
        ("SequenceGap", (2, 1)), ("Packet", 3),
        ("LinkError", NakCode.TRUNCATED),
        ("LinkError", NakCode.TRUNCATED),
        ("LinkError", NakCode.OVERSIZE),
        ("LinkError", NakCode.OVERSIZE),
        ("LinkError", NakCode.BAD_LENGTH),
        ("SequenceGap", (4, 1)), ("Packet", 5), ("Packet", 6),
        ("SequenceGap", (7, 2)), ("Packet", 9),
    ]
    assert items[1] == Packet(PacketType.EVENTS, 0, b"\x00\x00\x00")
    c = decoder.counters
    assert c.bytes == len(stream)
    assert (c.packets, c.payload_bytes) == (6, 18)
    assert c.errors == {NakCode.BAD_CRC: 1, NakCode.TRUNCATED: 2, NakCode.OVERSIZE: 2,
                        NakCode.BAD_LENGTH: 1}
    assert c.dropped_frames == 6
    assert (c.sequence_gaps, c.missing_packets) == (3, 4)
    assert (c.resyncs, c.skipped_bytes) == (1, 3)


def test_decoder_byte_by_byte_equals_bulk():
    rng = random.Random(3)
    stream = bytearray()
    for seq in range(60):
        frame = bytearray(protocol.encode_frame(rng.choice(list(PacketType)), seq,
                                             bytes(rng.randint(0, 255)
                                                   for _ in range(rng.randint(0, MAX_PAYLOAD)))))
        if rng.random() < 0.3:
            frame[rng.randrange(len(frame))] ^= 1 << rng.randrange(8)
        stream += frame
    bulk = protocol.FrameDecoder(synced=True)
    whole = bulk.feed(stream)
    split = protocol.FrameDecoder(synced=True)
    pieces = []
    position = 0
    while position < len(stream):
        step = rng.randint(1, 40)
        pieces += split.feed(stream[position:position + step])
        position += step
    assert pieces == whole
    assert split.counters == bulk.counters
    assert bulk.counters.packets > 20 and bulk.counters.dropped_frames > 5


def test_decoder_memory_bounded():
    decoder = protocol.FrameDecoder(synced=True)
    for _ in range(100):
        assert decoder.feed(b"\x55" * 1000) == []
        assert len(decoder._frame) <= MAX_ENCODED + 1
    items = decoder.feed(b"\x00")
    assert [item.code for item in items] == [NakCode.OVERSIZE]


def test_packet_encoder_numbers_packets():
    encoder = protocol.PacketEncoder(seq=254)
    decoder = protocol.FrameDecoder(synced=True)
    stream = b"".join(encoder.frame(PacketType.PING) for _ in range(4))
    assert [item.seq for item in decoder.feed(stream)] == [254, 255, 0, 1]
    assert decoder.counters.sequence_gaps == 0


# Event batches

def test_events_round_trip():
    rng = np.random.default_rng(4)
    events = np.zeros(MAX_EVENTS_PER_PACKET, dtype=EVENT_DTYPE)
    events["timestamp"] = rng.integers(0, 1 << 13, len(events))
    events["address"] = rng.integers(0, 1 << 6, len(events))
    events["collision"] = rng.integers(0, 2, len(events))
    events["pulse"] = rng.integers(0, 1 << 32, len(events), dtype=np.uint64)
    payload = protocol.pack_events(events)
    assert len(payload) == len(events) * EVENT_BYTES <= MAX_PAYLOAD
    first = int.from_bytes(payload[:EVENT_BYTES], "little")
    assert first & 0x1fff == events["timestamp"][0]           # the struct's first field
    assert first >> 20 == events["pulse"][0]                  # after 13 + 6 + 1 bits
    assert np.array_equal(protocol.unpack_events(payload), events)
    with pytest.raises(ValueError, match=r"^Event payload of 8 bytes is not a whole number of "
                                         r"7-byte events$"):
        protocol.unpack_events(bytes(8))
