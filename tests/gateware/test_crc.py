"""CRC stages (append, check and remove) against the host codec's CRC-16, bit for bit."""

import binascii
import random

import pytest
from amaranth.lib.crc import catalog

from fliss.hdl.link.crc import LINK_CRC, CrcAppender, CrcChecker
from fliss.hdl.protocol import CRC_BYTES, CRC_CHECK
from fliss import protocol

from simulation import simulate, stream_put, stream_put_all, stream_get_each


def random_packets(rng, count):
    packets = [b"\x00", b"\xff", b"123456789"]
    for _ in range(count):
        length = rng.choice([1, 2, 3, rng.randint(1, 40), rng.randint(1, 300)])
        packets.append(bytes(rng.choice([0, rng.randint(0, 255)]) for _ in range(length)))
    return packets


def test_link_crc_is_the_catalogue_crc16_ibm_3740():
    for field in ("crc_width", "polynomial", "initial_crc", "reflect_input", "reflect_output",
                  "xor_output"):
        assert getattr(LINK_CRC, field) == getattr(catalog.CRC16_IBM_3740, field)
    assert LINK_CRC(8).compute(b"123456789") == CRC_CHECK
    data = bytes(random.Random(1).randint(0, 255) for _ in range(300))
    assert LINK_CRC(8).compute(data) == protocol.crc16(data) == binascii.crc_hqx(data, 0xffff)


@pytest.mark.parametrize("seed, idle", [(2, 0.0), (3, 0.5)])
def test_crc_appender_matches_codec(seed, idle):
    rng = random.Random(seed)
    packets = random_packets(rng, 20)
    expected = []
    for packet in packets:
        body = packet + protocol.crc16(packet).to_bytes(CRC_BYTES, "big")
        expected += [(byte, int(index == len(body) - 1)) for index, byte in enumerate(body)]
    dut = CrcAppender()
    received = []

    async def send(ctx):
        await stream_put_all(ctx, dut.i, ({"data": byte, "last": index == len(packet) - 1}
                                          for packet in packets
                                          for index, byte in enumerate(packet)),
                             rng=rng, idle=idle)
        await ctx.tick().repeat(200)

    async def collect(ctx):
        async for item in stream_get_each(ctx, dut.o, rng=rng, idle=idle):
            received.append((item.data, item.last))

    simulate(dut, send, background=[collect])
    assert received == expected


def checked_frames(rng, count):
    """(bytes, verdict) frames: good packets with their CRC, damaged ones, and frames shorter
    than the CRC. The verdict (empty, truncated, oversize) is random: the checker passes it on."""
    frames = [(b"", 0), (b"\x12", 1), (b"\x00\x00", 2), (protocol.encode_packet(1, 2, b""), 3)]
    for packet in random_packets(rng, count):
        body = packet + protocol.crc16(packet).to_bytes(CRC_BYTES, "big")
        if rng.random() < 0.3:
            body = bytearray(body)
            body[rng.randrange(len(body))] ^= 1 << rng.randrange(8)
        frames.append((bytes(body), rng.randrange(8)))
    return frames


@pytest.mark.parametrize("seed, idle", [(4, 0.0), (5, 0.5)])
def test_crc_checker_matches_codec(seed, idle):
    rng = random.Random(seed)
    frames = checked_frames(rng, 25)
    expected = []
    for body, verdict in frames:
        expected += [("byte", byte) for byte in body[:-CRC_BYTES]]
        expected.append(("end", verdict, int(len(body) < CRC_BYTES),
                         int(protocol.crc16(body) != 0)))
    dut = CrcChecker()
    received = []

    async def send(ctx):
        for body, verdict in frames:
            await stream_put_all(ctx, dut.i, ({"data": byte, "end": 0} for byte in body),
                                 rng=rng, idle=idle)
            await stream_put(ctx, dut.i, {"end": 1, "verdict": {
                "empty": verdict & 1, "truncated": verdict >> 1 & 1, "oversize": verdict >> 2}})
        await ctx.tick().repeat(200)

    async def collect(ctx):
        async for item in stream_get_each(ctx, dut.o, rng=rng, idle=idle):
            if item.end:
                verdict = (item.verdict.empty | item.verdict.truncated << 1 |
                           item.verdict.oversize << 2)
                received.append(("end", verdict, item.short, item.bad_crc))
            else:
                received.append(("byte", item.data))

    simulate(dut, send, background=[collect])
    assert received == expected
    ends = [item for item in expected if item[0] == "end"]
    assert sum(item[3] for item in ends) >= 5 and sum(not item[3] for item in ends) >= 10
