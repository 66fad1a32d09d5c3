"""Bulk decoder (fliss.host.bulk) against the scalar FrameDecoder and StreamAssembler.

Every stream is decoded by both; packets, reports, events and counters must be identical, on
clean streams and on streams damaged every way a link can damage them.
"""

import binascii
import os

import numpy as np
import pytest
from amaranth.lib import data

from fliss.hdl.event import Event
from fliss.hdl.protocol import (HISTOGRAM_COUNT_BITS, PacketType, NakCode, MAX_EVENTS_PER_PACKET,
                                MAX_ENCODED, HistogramChunk, HEADER_BYTES, CRC_BYTES, EVENT_BYTES)
from fliss.host import bulk
from fliss.host.stream import EventBatch, StreamAssembler
from fliss.protocol.frames import FrameDecoder, Packet, LinkError, encode_frame
from fliss.protocol.cobs import cobs_encode
from fliss.protocol.crc import crc16
from fliss.protocol.layout import pack, pack_words
from fliss.protocol.events import pack_events
from fliss.protocol.events import EVENT_DTYPE


# Streams

def random_events(rng, count, *, big=False):
    """Events with every field random within its width; ``big`` makes every byte non-zero
    (a full 37-event packet then has a 254-byte run: a full COBS block)."""
    events = np.zeros(count, dtype=EVENT_DTYPE)
    for name, field in data.Layout.cast(Event):
        low = (1 << (field.width - 1)) if big else 0
        events[name] = rng.integers(low, 1 << field.width, count, dtype=np.uint64)
    if big:     # no zero byte in the 7 bytes of an event
        events["timestamp"] |= 0x101
        events["pulse"] |= 0x01010101
    return events


def histogram_payload(rng, frame, first, bins=128, last=False):
    counts = rng.poisson(3.0, bins)
    return pack(HistogramChunk, frame=frame, first_bin=first, shift=0, last=int(last)) + \
        pack_words(counts, HISTOGRAM_COUNT_BITS)


def mixed_frames(rng, *, packets=300, seq=0):
    """Wire frames of a device: runs of full EVENTS packets, short EVENTS packets, HISTOGRAM
    chunks, replies, and a few packets of unusual shape; with their events in order."""
    frames, events = [], []
    chunk = 0
    for _ in range(packets):
        kind = rng.random()
        if kind < 0.6:
            batch = random_events(rng, MAX_EVENTS_PER_PACKET)
            frames.append(encode_frame(PacketType.EVENTS, seq, pack_events(batch)))
            events.append(batch)
        elif kind < 0.7:
            batch = random_events(rng, int(rng.integers(0, MAX_EVENTS_PER_PACKET)))
            frames.append(encode_frame(PacketType.EVENTS, seq, pack_events(batch)))
            events.append(batch)
        elif kind < 0.85:
            frames.append(encode_frame(PacketType.HISTOGRAM, seq,
                                       histogram_payload(rng, 0, 128 * chunk)))
            chunk = (chunk + 1) % 64
        elif kind < 0.9:
            frames.append(encode_frame(PacketType.ACK, seq, bytes([int(rng.integers(256))])))
        elif kind < 0.93:       # an EVENTS payload that is not a whole number of events
            frames.append(encode_frame(PacketType.EVENTS, seq, rng.bytes(10)))
        elif kind < 0.96:       # full COBS blocks
            batch = random_events(rng, MAX_EVENTS_PER_PACKET, big=True)
            frames.append(encode_frame(PacketType.EVENTS, seq, pack_events(batch)))
            events.append(batch)
        else:                   # unknown type
            frames.append(encode_frame(0x9f, seq, rng.bytes(int(rng.integers(0, 40)))))
        seq = (seq + 1) % 256
    return frames, events


def bad_length_frame(seq, payload):
    """A frame whose CRC is right but whose header's length is not its payload's."""
    body = bytes([PacketType.EVENTS.value, seq]) + (len(payload) + 1).to_bytes(2, "little") + \
        payload
    return cobs_encode(body + crc16(body).to_bytes(2, "big")) + b"\x00"


def damage(rng, stream, count):
    """``count`` random faults: bit flips, bytes lost, noise inserted, a byte changed."""
    stream = bytearray(stream)
    for _ in range(count):
        where = int(rng.integers(0, len(stream)))
        kind = rng.random()
        if kind < 0.4:
            stream[where] ^= 1 << int(rng.integers(8))
        elif kind < 0.6:
            del stream[where:where + int(rng.integers(1, 300))]
        elif kind < 0.8:
            stream[where:where] = rng.bytes(int(rng.integers(1, 40)))
        else:
            stream[where] = int(rng.integers(1, 256))
    return bytes(stream)


# References

def scalar_decode(stream, *, synced, reads):
    """The scalar path: FrameDecoder fed ``reads`` (sizes), StreamAssembler for data packets."""
    decoder = FrameDecoder(synced=synced)
    assembler = StreamAssembler()
    items, batches = [], []
    start = 0
    for size in reads:
        for item in decoder.feed(stream[start:start + size]):
            items.append(item)
            if isinstance(item, Packet) and \
                    item.type in (PacketType.EVENTS, PacketType.HISTOGRAM):
                batches += [b.events for b in assembler.add(item, 0.0)
                            if isinstance(b, EventBatch)]
        start += size
    return items, batches, decoder.counters, assembler.counters


def read_sizes(rng, length, largest):
    sizes = []
    while sum(sizes) < length:
        sizes.append(int(rng.integers(1, largest + 1)))
    return sizes


def check_same(stream, *, synced=True, reads=None, min_group=bulk.BULK_MIN_GROUP):
    """Decode ``stream`` both ways, with :meth:`BulkDecoder.feed` and with
    :meth:`BulkDecoder.feed_events`, and compare everything. Returns the scalar counters."""
    reads = [len(stream)] if reads is None else reads
    items, batches, counters, stream_counters = scalar_decode(stream, synced=synced, reads=reads)

    decoder = bulk.BulkDecoder(synced=synced, min_bytes=0, min_group=min_group)
    got, start = [], 0
    for size in reads:
        got += decoder.feed(stream[start:start + size])
        start += size
    assert got == items
    assert decoder.counters == counters

    decoder = bulk.BulkDecoder(synced=synced, min_bytes=0, min_group=min_group)
    others, events, counts, start = [], [], [], 0
    for size in reads:
        decoded = decoder.feed_events(stream[start:start + size])
        others += decoded.items
        events.append(decoded.events)
        counts.append(decoded.event_counts)
        assert [len(b) for b in decoded.batches()] == list(decoded.event_counts)
        start += size
    assert decoder.counters == counters
    whole = [item for item in items if not (
        isinstance(item, Packet) and item.type == PacketType.EVENTS and
        len(item.payload) % 7 == 0)]
    assert others == whole
    assert list(np.concatenate(counts)) == [len(b) for b in batches]
    expected = np.concatenate(batches) if batches else np.zeros(0, EVENT_DTYPE)
    assert np.concatenate(events).dtype == EVENT_DTYPE
    assert np.array_equal(np.concatenate(events), expected)

    # The rest of the client's path: the packets left in ``items`` give the same stream counters.
    assembler = StreamAssembler()
    for item in others:
        if isinstance(item, Packet) and item.type in (PacketType.EVENTS, PacketType.HISTOGRAM):
            assembler.add(item, 0.0)
    assert assembler.counters.malformed == stream_counters.malformed
    assert assembler.counters.histogram_chunks == stream_counters.histogram_chunks
    assert int(np.concatenate(counts).sum()) == stream_counters.events
    return counters


# CRC

@pytest.mark.parametrize("length", [0, 1, 2, 3, 6, 7, 264, 265, 270])
def test_crc_rows_against_binascii(length):
    rng = np.random.default_rng(length)
    rows = rng.integers(0, 256, (50, length), dtype=np.uint8)
    expected = [binascii.crc_hqx(row.tobytes(), 0xffff) for row in rows]
    assert bulk.crc_rows(rows).tolist() == expected
    # Strided rows (a view into a wider array) give the same.
    wide = np.zeros((50, length + 3), dtype=np.uint8)
    wide[:, 1:length + 1] = rows
    assert bulk.crc_rows(wide[:, 1:length + 1]).tolist() == expected


# Clean streams

def test_clean_event_stream():
    rng = np.random.default_rng(1)
    events = random_events(rng, 3000)
    stream = b"".join(encode_frame(PacketType.EVENTS, n % 256,
                                   pack_events(events[start:start + MAX_EVENTS_PER_PACKET]))
                      for n, start in enumerate(range(0, len(events), MAX_EVENTS_PER_PACKET)))
    decoded, counters = bulk.decode_stream(stream)
    assert np.array_equal(decoded.events, events)           # against the source, not a decoder
    assert decoded.items == []
    assert counters.packets == len(decoded.event_counts) == -(-3000 // MAX_EVENTS_PER_PACKET)
    assert counters.dropped_frames == counters.missing_packets == 0
    assert counters.bytes == len(stream)
    check_same(stream)


def test_clean_mixed_stream():
    rng = np.random.default_rng(2)
    frames, events = mixed_frames(rng)
    stream = b"".join(frames)
    decoded, _ = bulk.decode_stream(stream)
    assert np.array_equal(decoded.events, np.concatenate(events))
    counters = check_same(stream)
    assert counters.dropped_frames == 0 and counters.sequence_gaps == 0
    check_same(stream, min_group=1)


def test_full_cobs_blocks_in_a_group():
    # Enough frames with a full 254-byte block for a bulk group of their own.
    rng = np.random.default_rng(3)
    frames = [encode_frame(PacketType.EVENTS, seq, pack_events(
        random_events(rng, MAX_EVENTS_PER_PACKET, big=seq % 2 == 0))) for seq in range(60)]
    assert any(b"\xff" in frame[:20] for frame in frames)
    check_same(b"".join(frames), min_group=4)


# Damaged streams

@pytest.mark.parametrize("seed", range(6))
def test_damaged_stream(seed):
    rng = np.random.default_rng(10 + seed)
    frames, _ = mixed_frames(rng, packets=250, seq=int(rng.integers(256)))
    # Dropped frames (sequence gaps), a frame with a wrong length, then damage of every kind.
    frames = [frame for frame in frames if rng.random() > 0.05]
    frames.insert(int(rng.integers(len(frames))), bad_length_frame(7, rng.bytes(14)))
    stream = damage(rng, b"".join(frames), 25)
    synced = bool(seed % 2)
    counters = check_same(stream, synced=synced, reads=read_sizes(rng, len(stream), 9000),
                          min_group=[1, 4, 16][seed % 3])
    assert counters.sequence_gaps and counters.dropped_frames


def test_every_kind_of_damage_is_found():
    # Faults made on purpose, one kind at a time, in groups large enough for the bulk path.
    rng = np.random.default_rng(4)
    frames, _ = mixed_frames(rng, packets=400)
    # full EVENTS frames: packet, one COBS code byte (zeros break the runs), delimiter
    full_length = HEADER_BYTES + MAX_EVENTS_PER_PACKET * EVENT_BYTES + CRC_BYTES + 2
    full = [i for i, frame in enumerate(frames) if len(frame) == full_length]
    frames = list(frames)
    for i in full[0:40:4]:              # a byte changed, not to zero: BAD_CRC (mostly)
        frames[i] = frames[i][:100] + bytes([frames[i][100] % 255 + 1]) + frames[i][101:]
    for i in full[40:80:4]:             # cut short: the last block runs past the delimiter
        frames[i] = frames[i][:-4] + b"\x00"
    for i in full[80:100:4]:            # a delimiter lost: two frames in one, OVERSIZE
        frames[i] = frames[i][:-1]
    frames.insert(5, bad_length_frame(1, b"\x01" * 21))
    stream = b"".join(frames)
    counters = check_same(stream, min_group=2)
    errors = counters.errors
    assert errors[NakCode.BAD_CRC] and errors[NakCode.TRUNCATED] and errors[NakCode.OVERSIZE]
    assert errors[NakCode.BAD_LENGTH] == 1


def test_noise_only():
    rng = np.random.default_rng(5)
    for synced in (False, True):
        noise = rng.integers(0, 256, 20000, dtype=np.uint8)
        noise[rng.random(20000) < 0.004] = 0        # sparse delimiters: long frames too
        check_same(noise.tobytes(), synced=synced, min_group=1)
        check_same(noise.tobytes(), synced=synced, reads=read_sizes(rng, 20000, 5000))


def test_starts_mid_frame_and_reads_cut_frames():
    rng = np.random.default_rng(6)
    frames, _ = mixed_frames(rng, packets=200)
    stream = b"".join(frames)[123:]
    for largest in (5000, 600, 50):
        check_same(stream, synced=False, reads=read_sizes(rng, len(stream), largest),
                   min_group=4)


def test_oversize_frame_keeps_only_the_start():
    rng = np.random.default_rng(7)
    frames, _ = mixed_frames(rng, packets=60)
    long = bytes(rng.integers(1, 256, 3 * MAX_ENCODED, dtype=np.uint8)) + b"\x00"
    stream = b"".join(frames[:30]) + long + b"".join(frames[30:])
    decoder = bulk.BulkDecoder(synced=True, min_bytes=0)
    errors = [item for item in decoder.feed(stream) if isinstance(item, LinkError)]
    assert [e.code for e in errors] == [NakCode.OVERSIZE]
    assert errors[0].frame == long[:MAX_ENCODED + 1]
    check_same(stream)


def test_feed_and_feed_events_mix_on_one_stream():
    rng = np.random.default_rng(8)
    frames, events = mixed_frames(rng, packets=300)
    stream = b"".join(frames)
    scalar = FrameDecoder(synced=True)
    expected = scalar.feed(stream)
    decoder = bulk.BulkDecoder(synced=True, min_bytes=0, min_group=4)
    got, pieces, start = [], [], 0
    for number, size in enumerate(read_sizes(rng, len(stream), 20000)):
        chunk = stream[start:start + size]
        start += size
        if number % 2:
            got += decoder.feed(chunk)
        else:
            decoded = decoder.feed_events(chunk)
            # Put the events back as packets, so that both halves compare as one list.
            got += decoded.items
            pieces += decoded.batches()
    assert decoder.counters == scalar.counters
    reports = [item for item in expected if not isinstance(item, Packet)]
    assert [item for item in got if not isinstance(item, Packet)] == reports
    in_packets = [item for item in got if isinstance(item, Packet) and
                  item.type == PacketType.EVENTS and len(item.payload) % 7 == 0]
    assert len(in_packets) + len(pieces) == sum(
        1 for item in expected if isinstance(item, Packet) and
        item.type == PacketType.EVENTS and len(item.payload) % 7 == 0)


def test_small_reads_go_to_the_scalar_decoder():
    rng = np.random.default_rng(9)
    frames, _ = mixed_frames(rng, packets=20)
    stream = b"".join(frames)
    decoder = bulk.BulkDecoder(synced=True, min_bytes=len(stream) + 1)
    reference = FrameDecoder(synced=True)
    assert decoder.feed(stream) == reference.feed(stream)
    assert decoder.counters == reference.counters


# The client

def test_reply_timeout_is_longer_on_a_pty(tmp_path):
    from fliss.host.port import default_timeout, is_pty, DEFAULT_TIMEOUT_S, PTY_TIMEOUT_S
    master, slave = os.openpty()
    try:
        path = os.ttyname(slave)
        link = tmp_path / "tty"
        link.symlink_to(path)
        assert is_pty(path) and is_pty(str(link))
        assert default_timeout(path) == PTY_TIMEOUT_S > DEFAULT_TIMEOUT_S
    finally:
        os.close(master)
        os.close(slave)
    for port in ("loop://", "socket://localhost:7", "/dev/null", str(tmp_path / "none")):
        assert not is_pty(port) and default_timeout(port) == DEFAULT_TIMEOUT_S
