"""Frame encoder, frame decoder and CRC-16 gateware against the host codec, bit for bit."""

import binascii
import random

import pytest
from amaranth.hdl import Elaboratable, Module
from amaranth.lib import wiring

from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.hdl.link.crc import Crc16
from fliss.hdl.link.framing import FrameEncoder, FrameDecoder
from fliss.hdl.protocol import (PacketType, NakCode, MAX_PAYLOAD, MAX_ENCODED, CRC_BYTES, CRC_CHECK,
                                COBS_MAX_RUN)
from fliss.hdl.link.uart import UartTx, UartRx
from fliss import protocol

from simulation import simulate, stream_put, stream_get, stream_put_all, Twins


def beats(packet):
    """PacketBeat values of a packet given as (type, seq, payload)."""
    type, seq, payload = packet
    header = {"type": int(type.value if isinstance(type, PacketType) else type), "seq": seq,
              "length": len(payload)}
    out = [{"header": header, "data": 0, "first": 1, "last": int(not payload)}]
    for index, byte in enumerate(payload):
        out.append({"header": header, "data": byte, "first": 0,
                    "last": int(index == len(payload) - 1)})
    return out


async def put_packets(ctx, stream, packets, rng, idle=0.0):
    await stream_put_all(ctx, stream, (beat for packet in packets for beat in beats(packet)),
                         rng=rng, idle=idle)


async def get_packets(ctx, stream, rng, out, idle=0.0):
    """Collect packets forever into `out` as (type, seq, payload), checking the beat framing."""
    while True:
        if rng.random() < idle:
            await ctx.tick().repeat(rng.randint(1, 5))
        beat = await stream_get(ctx, stream)
        assert beat.first == 1
        header = beat.header
        payload = bytearray()
        last = beat.last
        while not last:
            if rng.random() < idle:
                await ctx.tick().repeat(rng.randint(1, 5))
            beat = await stream_get(ctx, stream)
            assert beat.first == 0
            assert beat.header.as_bits() == header.as_bits()   # header held in every beat
            payload.append(beat.data)
            last = beat.last
        assert header.length == len(payload)
        out.append((int(header.type), int(header.seq), bytes(payload)))


def nonzero_bytes(rng, count):
    return bytes(rng.randint(1, 255) for _ in range(count))


def edge_packets(rng):
    """Packets around the COBS corner cases: empty payloads, maximum payload, zero CRC bytes,
    a full 254-byte run ending with the packet, long zero runs."""
    packets = [
        (PacketType.PING, 0, b""),
        (PacketType.START, 255, b""),
        (PacketType.EVENTS, 1, bytes(MAX_PAYLOAD)),
        (PacketType.HISTOGRAM, 2, nonzero_bytes(rng, MAX_PAYLOAD)),
        (PacketType.WRITE, 3, b"\x00"),
        (PacketType.WRITE, 4, b"\x00\x00\xff"),
    ]
    # A run of exactly COBS_MAX_RUN non-zero bytes that ends with the last CRC byte.
    while True:
        payload = b"\x00" + nonzero_bytes(rng, COBS_MAX_RUN - CRC_BYTES)
        crc = protocol.encode_packet(PacketType.HISTOGRAM, 5, payload)[-CRC_BYTES:]
        if 0 not in crc:
            packets.append((PacketType.HISTOGRAM, 5, payload))
            break
    # Zero in the last CRC byte; zero in the first.
    for position in (-1, -2):
        while True:
            payload = nonzero_bytes(rng, rng.randint(1, 20))
            packet = protocol.encode_packet(PacketType.STATUS, 6, payload)
            if packet[position] == 0:
                packets.append((PacketType.STATUS, 6, payload))
                break
    return packets


def random_packets(rng, count):
    packets = []
    for _ in range(count):
        length = rng.choice([0, 1, 2, 7, rng.randint(0, 40), rng.randint(0, MAX_PAYLOAD)])
        zeros = rng.random()
        payload = bytes(0 if rng.random() < zeros * 0.3 else rng.randint(1, 255)
                        for _ in range(length))
        packets.append((rng.choice(list(PacketType)), rng.randint(0, 255), payload))
    return packets


# CRC

def test_crc16_gateware():
    rng = random.Random(1)
    data = b"123456789" + bytes(rng.randint(0, 255) for _ in range(200))
    dut = Crc16()

    async def testbench(ctx):
        ctx.set(dut.clear, 1)
        await ctx.tick()
        ctx.set(dut.clear, 0)
        ctx.set(dut.valid, 1)
        for index, byte in enumerate(data):
            ctx.set(dut.data, byte)
            await ctx.tick()
            if index == 8:
                assert ctx.get(dut.crc) == CRC_CHECK
            expected = protocol.crc16(data[:index + 1])
            assert ctx.get(dut.crc) == expected == binascii.crc_hqx(data[:index + 1], 0xffff)
        # The CRC of a packet, CRC included, is zero.
        for byte in protocol.crc16(data).to_bytes(CRC_BYTES, "big"):
            ctx.set(dut.data, byte)
            await ctx.tick()
        assert ctx.get(dut.crc) == 0

    simulate(dut, testbench)


# Encoder

@pytest.mark.parametrize("idle", [0.0, 0.5])
def test_encoder_matches_codec(idle):
    rng = random.Random(int(idle * 10) + 2)
    packets = edge_packets(rng) + random_packets(rng, 12)
    expected = b"".join(protocol.encode_frame(*packet) for packet in packets)
    dut = FrameEncoder()
    received = bytearray()

    async def send(ctx):
        await put_packets(ctx, dut.i, packets, rng, idle)

    async def collect(ctx):
        while len(received) < len(expected):
            if rng.random() < idle:
                await ctx.tick().repeat(rng.randint(1, 4))
            received.append(await stream_get(ctx, dut.o, timeout=1000))
        await ctx.tick().repeat(20)
        assert ctx.get(dut.o.valid) == 0

    simulate(dut, send, collect)
    assert bytes(received) == expected


def test_encoder_drops_and_counts_stray_beats():
    rng = random.Random(9)
    packet = (PacketType.PING, 7, b"\x01\x00")
    header = {"type": PacketType.PING.value, "seq": 7, "length": 2}
    stray = [{"header": header, "data": 0x55, "first": 0, "last": 0},
             {"header": header, "data": 0x66, "first": 0, "last": 1}]
    expected = protocol.encode_frame(*packet) * 2
    dut = FrameEncoder()
    received = bytearray()

    async def send(ctx):
        for beat in stray:
            await stream_put(ctx, dut.i, beat)
        await put_packets(ctx, dut.i, [packet], rng)
        await stream_put(ctx, dut.i, stray[0])
        await put_packets(ctx, dut.i, [packet], rng)

    async def collect(ctx):
        while len(received) < len(expected):
            received.append(await stream_get(ctx, dut.o, timeout=1000))
        assert ctx.get(dut.stray_beats) == 3

    simulate(dut, send, collect)
    assert bytes(received) == expected


# Decoder

def corrupt_stream(rng, packets):
    """Frames with every kind of damage between good ones; returns the byte stream."""
    stream = bytearray()
    for packet in packets:
        frame = protocol.encode_frame(*packet)
        kind = rng.choice(["good", "good", "good", "flip", "truncate", "garbage", "oversize",
                           "length", "delimiters", "tail"])
        if kind == "flip":
            frame = bytearray(frame)
            index = rng.randrange(len(frame) - 1)
            frame[index] ^= 1 << rng.randrange(8)
            stream += frame
        elif kind == "truncate":
            stream += frame[:rng.randrange(1, len(frame) - 1)] + b"\x00"
        elif kind == "garbage":
            stream += bytes(rng.randint(0, 255) for _ in range(rng.randint(1, 30))) + b"\x00"
            stream += frame
        elif kind == "oversize":
            type, seq, payload = packet
            body = protocol.frames._header_bytes(type, seq, MAX_PAYLOAD + 1) + bytes(MAX_PAYLOAD + 1)
            body += protocol.crc16(body).to_bytes(CRC_BYTES, "big")
            stream += protocol.cobs_encode(body) + b"\x00"
            stream += nonzero_bytes(rng, MAX_ENCODED + rng.randint(1, 3)) + b"\x00"
        elif kind == "length":
            type, seq, payload = packet
            body = protocol.frames._header_bytes(type, seq, len(payload) + 1) + payload
            body += protocol.crc16(body).to_bytes(CRC_BYTES, "big")
            stream += protocol.cobs_encode(body) + b"\x00"
        elif kind == "delimiters":
            stream += b"\x00\x00" + frame + b"\x00"
        elif kind == "tail":
            stream += b"\x05\x01" + b"\x00" + frame   # short frame, then a good one
        else:
            stream += frame
    return bytes(stream)


def check_decoder(stream, rng, *, idle_in=0.0, idle_out=0.0, registered_read=False):
    model = protocol.FrameDecoder(synced=True)
    items = model.feed(stream)
    expected_packets = [(int(p.type.value if isinstance(p.type, PacketType) else p.type),
                         p.seq, p.payload) for p in items if isinstance(p, protocol.Packet)]
    expected_drops = [e.code for e in items if isinstance(e, protocol.LinkError)]

    dut = FrameDecoder(registered_read=registered_read)
    packets, drops = [], []

    async def send(ctx):
        await stream_put_all(ctx, dut.i, stream, rng=rng, idle=idle_in)
        await ctx.tick().repeat(8 * MAX_PAYLOAD + 50)    # (the last payload out, at idle_out)
        counts = {NakCode.BAD_CRC: ctx.get(dut.bad_crc), NakCode.TRUNCATED: ctx.get(dut.truncated),
                  NakCode.OVERSIZE: ctx.get(dut.oversize),
                  NakCode.BAD_LENGTH: ctx.get(dut.bad_length)}
        assert counts == model.counters.errors
        assert ctx.get(dut.packets) == model.counters.packets

    async def collect(ctx):
        await get_packets(ctx, dut.o, rng, packets, idle_out)

    async def monitor(ctx):
        async for _, _, drop, reason in ctx.tick().sample(dut.drop, dut.drop_reason):
            if drop:
                drops.append(reason)

    simulate(dut, send, background=[collect, monitor])
    assert packets == expected_packets
    assert drops == expected_drops
    return len(expected_packets), len(expected_drops)


#: The decoder's two ways of reading its payload buffer: a plain memory (the iCEBreaker) and a
#: registered block RAM read (the ULX3S).
READS = pytest.mark.parametrize("registered_read", [False, True], ids=["plain", "registered"])


@READS
def test_decoder_good_packets(registered_read):
    rng = random.Random(3)
    packets = edge_packets(rng) + random_packets(rng, 10)
    stream = b"".join(protocol.encode_frame(*packet) for packet in packets)
    good, dropped = check_decoder(stream, rng, registered_read=registered_read)
    assert good == len(packets) and dropped == 0


@READS
@pytest.mark.parametrize("seed, idle_in, idle_out", [(4, 0.0, 0.0), (5, 0.3, 0.6)])
def test_decoder_damaged_frames(seed, idle_in, idle_out, registered_read):
    rng = random.Random(seed)
    packets = random_packets(rng, 30)
    stream = corrupt_stream(rng, packets)
    good, dropped = check_decoder(stream, rng, idle_in=idle_in, idle_out=idle_out,
                                  registered_read=registered_read)
    assert good >= 10 and dropped >= 10


def test_decoder_reads_give_the_same_beats_cycle_for_cycle():
    rng = random.Random(11)
    stream = corrupt_stream(rng, random_packets(rng, 30))
    dut = Twins(FrameDecoder(registered_read=False), FrameDecoder(registered_read=True))

    async def send(ctx):
        await stream_put_all(ctx, dut.first.i, stream, rng=rng, idle=0.3)
        await ctx.tick().repeat(8 * MAX_PAYLOAD + 50)

    assert dut.run_compared(send, rng=rng, ready=0.5) > 500


@READS
def test_decoder_random_bytes_then_resync(registered_read):
    rng = random.Random(6)
    noise = bytes(rng.choice([0, rng.randint(1, 255)]) if rng.random() < 0.05
                  else rng.randint(1, 255) for _ in range(1500))
    packets = random_packets(rng, 3)
    stream = noise + b"\x00" + b"".join(protocol.encode_frame(*p) for p in packets)
    good, dropped = check_decoder(stream, rng, registered_read=registered_read)
    assert good == 3 and dropped >= 1


@READS
def test_decoder_slow_consumer_stalls_input_without_loss(registered_read):
    # The consumer takes one beat in ten cycles; the input waits, nothing is dropped.
    rng = random.Random(7)
    packets = [(PacketType.WRITE, n, bytes(rng.randint(0, 255) for _ in range(60)))
               for n in range(4)]
    stream = b"".join(protocol.encode_frame(*p) for p in packets)
    good, dropped = check_decoder(stream, rng, idle_out=0.9, registered_read=registered_read)
    assert good == 4 and dropped == 0


# Encoder to decoder, directly and over the UART

class _Link(Elaboratable):
    def __init__(self, baud=None):
        self.encoder = FrameEncoder()
        self.decoder = FrameDecoder()
        self.baud = baud
        if baud:
            self.tx = UartTx(clock_hz=DEFAULT_CLOCK_HZ, baud=baud)
            self.rx = UartRx(clock_hz=DEFAULT_CLOCK_HZ, baud=baud)

    def elaborate(self, platform):
        m = Module()
        m.submodules.encoder = self.encoder
        m.submodules.decoder = self.decoder
        if self.baud:
            m.submodules.tx = self.tx
            m.submodules.rx = self.rx
            wiring.connect(m, self.encoder.o, self.tx.i)
            m.d.comb += self.rx.rx.eq(self.tx.tx)
            wiring.connect(m, self.rx.o, self.decoder.i)
        else:
            wiring.connect(m, self.encoder.o, self.decoder.i)
        return m


@pytest.mark.parametrize("baud", [None, 12_000_000])
def test_encoder_to_decoder(baud):
    rng = random.Random(8)
    packets = edge_packets(rng)[:2] + random_packets(rng, 6 if baud else 20)
    if baud:
        packets = [(t, s, p[:30]) for t, s, p in packets]
    expected = [(int(t.value), s, p) for t, s, p in packets]
    dut = _Link(baud)
    received = []

    async def send(ctx):
        await put_packets(ctx, dut.encoder.i, packets, rng, 0.2)

    async def collect(ctx):
        await get_packets(ctx, dut.decoder.o, rng, received, 0.2)

    async def wait(ctx):
        for _ in range(1000):
            if len(received) == len(packets):
                break
            await ctx.tick().repeat(100)
        if baud:
            assert ctx.get(dut.rx.framing_errors) == 0 and ctx.get(dut.rx.overruns) == 0
        assert ctx.get(dut.decoder.packets) == len(packets)

    simulate(dut, send, wait, background=[collect])
    assert received == expected
