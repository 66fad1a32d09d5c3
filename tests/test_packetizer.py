"""HISTOGRAM packets from a histogram readout, in Amaranth's simulator, against the protocol."""

import random

import pytest

from fliss.hdl.packetizer import HistogramPacketizer
from fliss.hdl.protocol import HISTOGRAM_COUNT_BITS, CHUNK_BINS, PacketType, HistogramChunk
from fliss.sim.codec import pack, pack_words
from simulation import simulate


def packetize(shift, frames, *, seed=0):
    """Feed ``frames`` (lists of bin counts) through the packetizer; return its packets as
    (type, length, payload bytes)."""
    dut = HistogramPacketizer()
    rng = random.Random(seed)
    packets = []

    async def source(ctx):
        ctx.set(dut.shift, shift)
        for counts in frames:
            for index, count in enumerate(counts):
                ctx.set(dut.readout.valid, 1)
                ctx.set(dut.readout.p.index, index)
                ctx.set(dut.readout.p.count, count)
                ctx.set(dut.readout.p.last, index == len(counts) - 1)
                await ctx.tick().until(dut.readout.ready)
                ctx.set(dut.readout.valid, 0)
                for _ in range(rng.randrange(0, 3)):
                    await ctx.tick()

        await ctx.tick().repeat(4 * CHUNK_BINS)     # the last chunk drains

    async def sink(ctx):
        while True:
            ready = rng.random() < 0.7
            ctx.set(dut.packets.ready, ready)
            if ready and ctx.get(dut.packets.valid):
                beat = ctx.get(dut.packets.p)
                if beat.first:
                    header = (beat.header.type, beat.header.length)
                    payload = bytearray()
                else:
                    payload.append(beat.data)
                if beat.last:
                    packets.append((*header, bytes(payload)))
            await ctx.tick()

    simulate(dut, source, background=[sink], clock_hz=100e6)
    return packets


@pytest.mark.parametrize("shift", [0, 5, 6, 7, 12, 13])
def test_histogram_chunks(shift):
    # Frames of 8192 >> shift bins go out as chunks of CHUNK_BINS bins at most, each with its
    # frame number, first bin, shift and a last-chunk flag, then the counts as u16 (the
    # HISTOGRAM payload of docs/protocol.md).
    bins = 8192 >> shift
    rng = random.Random(shift)
    # (two frames, for the frame number, where they are short)
    frames = [[rng.randrange(0, 1 << 16) for _ in range(bins)]
              for _ in range(2 if bins <= 1024 else 1)]
    want = []
    for number, counts in enumerate(frames):
        for first in range(0, bins, CHUNK_BINS):
            chunk = counts[first:first + CHUNK_BINS]
            last = int(first + CHUNK_BINS >= bins)
            payload = pack(HistogramChunk, frame=number, first_bin=first, shift=shift,
                           last=last) + pack_words(chunk, HISTOGRAM_COUNT_BITS)
            want.append((PacketType.HISTOGRAM.value, len(payload), payload))
    got = packetize(shift, frames, seed=shift)
    assert got == want
