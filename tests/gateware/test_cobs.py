"""COBS encoder and decoder stages against the host codec's COBS, bit for bit."""

import random

import pytest

from fliss.hdl.link.cobs import CobsEncoder, CobsDecoder
from fliss.hdl.protocol import COBS_MAX_RUN, MAX_ENCODED, MAX_PACKET
from fliss import protocol

from simulation import simulate, stream_put_all, stream_get_each, Twins


def nonzero_bytes(rng, count):
    return bytes(rng.randint(1, 255) for _ in range(count))


def corner_packets(rng):
    """Packets around COBS's corner cases: single bytes, zero runs, runs of 253 to 255 and 508
    non-zero bytes, a full run at the end, right before a zero, and right after one."""
    run = COBS_MAX_RUN
    return [
        b"\x00", b"\x01", b"\x00\x00", b"\x00" * 10, b"\xff",
        nonzero_bytes(rng, run - 1), nonzero_bytes(rng, run), nonzero_bytes(rng, run + 1),
        nonzero_bytes(rng, 2 * run),
        nonzero_bytes(rng, run) + b"\x00", b"\x00" + nonzero_bytes(rng, run),
        nonzero_bytes(rng, run) + b"\x00" + nonzero_bytes(rng, run),
        nonzero_bytes(rng, 3) + b"\x00" + nonzero_bytes(rng, run - 1) + b"\x00",
    ]


def random_packets(rng, count, longest=MAX_PACKET):
    packets = []
    for _ in range(count):
        length = rng.choice([1, 2, rng.randint(1, 40), rng.randint(1, longest)])
        zeros = rng.choice([0.0, 0.01, 0.1, 0.5])
        packets.append(bytes(0 if rng.random() < zeros else rng.randint(1, 255)
                             for _ in range(length)))
    return packets


# Encoder

def packet_bytes(packets):
    return ({"data": byte, "last": index == len(packet) - 1}
            for packet in packets for index, byte in enumerate(packet))


#: The encoder's two ways of reading its run buffer: a plain memory (the iCEBreaker) and a
#: registered block RAM read (the ULX3S).
@pytest.mark.parametrize("registered_read", [False, True], ids=["plain", "registered"])
@pytest.mark.parametrize("seed, idle", [(1, 0.0), (2, 0.5)])
def test_cobs_encoder_matches_codec(seed, idle, registered_read):
    rng = random.Random(seed)
    packets = corner_packets(rng) + random_packets(rng, 15)
    expected = b"".join(protocol.cobs_encode(packet) + b"\x00" for packet in packets)
    dut = CobsEncoder(registered_read=registered_read)
    received = bytearray()

    async def send(ctx):
        await stream_put_all(ctx, dut.i, packet_bytes(packets), rng=rng, idle=idle)
        await ctx.tick().repeat(2000)
        assert ctx.get(dut.o.valid) == 0

    async def collect(ctx):
        async for byte in stream_get_each(ctx, dut.o, rng=rng, idle=idle):
            received.append(byte)

    simulate(dut, send, background=[collect])
    assert bytes(received) == expected


def test_cobs_encoder_reads_give_the_same_bytes_cycle_for_cycle():
    rng = random.Random(9)
    packets = corner_packets(rng) + random_packets(rng, 15)
    dut = Twins(CobsEncoder(registered_read=False), CobsEncoder(registered_read=True))

    async def send(ctx):
        await stream_put_all(ctx, dut.first.i, packet_bytes(packets), rng=rng, idle=0.3)
        await ctx.tick().repeat(2000)

    sent = dut.run_compared(send, rng=rng, ready=0.6)
    assert sent == sum(len(protocol.cobs_encode(packet)) + 1 for packet in packets)


# Decoder

def decoder_model(stream, max_encoded):
    """What the decoder stage gives for ``stream``: ("byte", value) and ("end", empty,
    truncated, oversize) items. A cut block decodes as far as it goes."""
    items = []
    for frame in stream.split(b"\x00")[:-1]:
        index = 0
        while index < len(frame):       # find how far the last block is cut
            index += frame[index]
        missing = index - len(frame)
        if frame:
            decoded = protocol.cobs_decode(frame + b"\x01" * missing)
            decoded = decoded[:len(decoded) - missing]
            items += [("byte", byte) for byte in decoded]
        items.append(("end", int(not frame), int(missing != 0), int(len(frame) > max_encoded)))
    return items


def frames(rng, count):
    """Good, cut, oversize, garbage and empty frames, each ending with its delimiter."""
    stream = bytearray()
    for packet in corner_packets(rng) + random_packets(rng, count):
        frame = protocol.cobs_encode(packet)
        kind = rng.choice(["good", "good", "cut", "garbage", "empty", "oversize"])
        if kind == "cut":
            frame = frame[:rng.randrange(1, len(frame))]
        elif kind == "garbage":
            frame = nonzero_bytes(rng, rng.randint(1, 30))
        elif kind == "empty":
            frame = b""
        elif kind == "oversize":
            frame = nonzero_bytes(rng, MAX_ENCODED + rng.randint(-1, 3))
        stream += frame + b"\x00"
    return bytes(stream)


@pytest.mark.parametrize("seed, idle, max_encoded",
                         [(3, 0.0, MAX_ENCODED), (4, 0.5, MAX_ENCODED), (5, 0.2, 40)])
def test_cobs_decoder_matches_codec(seed, idle, max_encoded):
    rng = random.Random(seed)
    stream = frames(rng, 40)   # (enough for several oversize frames at every MAX_ENCODED)
    expected = decoder_model(stream, max_encoded)
    dut = CobsDecoder(max_encoded=max_encoded)
    received = []

    async def send(ctx):
        await stream_put_all(ctx, dut.i, stream, rng=rng, idle=idle)
        await ctx.tick().repeat(200)

    async def collect(ctx):
        async for item in stream_get_each(ctx, dut.o, rng=rng, idle=idle):
            if item.end:
                assert item.data == 0
                verdict = item.verdict
                received.append(("end", verdict.empty, verdict.truncated, verdict.oversize))
            else:
                received.append(("byte", item.data))

    simulate(dut, send, background=[collect])
    assert received == expected
    assert sum(item[0] == "end" and item[2] for item in expected) >= 5
    assert sum(item[0] == "end" and item[3] for item in expected) >= 3


def test_cobs_decoder_refuses_bad_length(construction_error):
    assert construction_error(lambda: CobsDecoder(max_encoded=0)) == \
        "Longest frame must be a positive integer, not 0"
