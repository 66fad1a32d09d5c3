"""HISTOGRAM and HISTOGRAM_COMPACT packets from the gateware, in Amaranth's simulator, against
the model (:func:`fliss.protocol.histograms.encode_histogram`) byte for byte."""

import random

import numpy as np
import pytest

from fliss.hdl.packets.histogram import HistogramPacketizer
from fliss.hdl.packets.histogram_full import FullHistogramPacketizer
from fliss.hdl.protocol import PacketType
from fliss.protocol.histograms import assemble, encode_histogram, frame_bins
from simulation import simulate


def packetize(frames, *, index_bits=16, seed=0, gaps=True, block=HistogramPacketizer):
    """Feed ``frames`` (``(counts, settings)`` with settings a dict of shift, pixel_bits,
    first_pixel, full_readout) through the packetizer ``block``; return its packets as (type,
    length, payload bytes)."""
    dut = block(index_bits=index_bits)
    rng = random.Random(seed)
    packets = []
    done = []

    async def source(ctx):
        for counts, settings in frames:
            for name, value in settings.items():
                ctx.set(getattr(dut, name), value)
            for index, count in enumerate(counts):
                ctx.set(dut.readout.valid, 1)
                ctx.set(dut.readout.p.index, index)
                ctx.set(dut.readout.p.count, int(count))
                ctx.set(dut.readout.p.last, index == len(counts) - 1)
                await ctx.tick().until(dut.readout.ready)
                ctx.set(dut.readout.valid, 0)
                if gaps:
                    for _ in range(rng.choice((0, 0, 0, 1, 3))):
                        await ctx.tick()
        while len(done) < len(frames):
            await ctx.tick()

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
                    if payload[7 if header[0] == PacketType.HISTOGRAM.value else 9] & 0x80:
                        done.append(True)       # the frame's last chunk
            await ctx.tick()

    simulate(dut, source, background=[sink], clock_hz=100e6)
    return packets


def model(frames, full=False):
    want = []
    for number, (counts, settings) in enumerate(frames):
        settings = dict(settings, full_readout=settings["full_readout"] or full)
        for type, payload in encode_histogram(counts, frame=number, **settings):
            want.append((type.value, len(payload), payload))
    return want


def settings(shift, pixel_bits=0, first_pixel=0, full_readout=0):
    return dict(shift=shift, pixel_bits=pixel_bits, first_pixel=first_pixel,
                full_readout=full_readout)


def random_frame(rng, shift, pixel_bits, density, top=1 << 16):
    bins = frame_bins(shift, pixel_bits)
    return np.where(rng.random(bins) < density, rng.integers(1, top, bins), 0)


@pytest.mark.parametrize("shift,pixel_bits", [(6, 0), (7, 2), (12, 0), (13, 0), (9, 1)])
def test_sparse_dense_empty_full_frames(shift, pixel_bits):
    # Frames of every kind one after the other (frame numbers count up): empty, sparse with
    # small and large counts, dense, every count 65535, and the same with full_readout.
    rng = np.random.default_rng(shift * 8 + pixel_bits)
    bins = frame_bins(shift, pixel_bits)
    kinds = [np.zeros(bins, np.int64), random_frame(rng, shift, pixel_bits, 0.02, 64),
             random_frame(rng, shift, pixel_bits, 0.1), random_frame(rng, shift, pixel_bits, 0.7),
             np.full(bins, 65535), random_frame(rng, shift, pixel_bits, 0.3, 64)]
    frames = [(counts, settings(shift, pixel_bits, first_pixel=64 - (1 << pixel_bits)))
              for counts in kinds]
    frames += [(counts, settings(shift, pixel_bits, full_readout=1)) for counts in kinds[1:3]]
    got = packetize(frames, seed=shift)
    assert got == model(frames)
    # (and the packets decode to the frames)
    decoded = assemble((type, payload) for type, _, payload in got)
    for number, (counts, _) in enumerate(frames):
        assert decoded[number][2] and np.array_equal(decoded[number][1], counts)
    if bins >= 128:
        types = {type for type, _, _ in got}
        assert types == {PacketType.HISTOGRAM.value, PacketType.HISTOGRAM_COMPACT.value}


def test_long_sparse_frame():
    # One pixel at full resolution (8192 bins) with a few hundred events, as the paper's
    # bench at a short integration time, then an empty one: each is one or a few compact
    # chunks, with runs of empty bins longer than 8191 (three-byte tokens).
    rng = np.random.default_rng(5)
    sparse = np.zeros(8192, np.int64)
    sparse[rng.integers(0, 8192, 300)] += 1
    sparse[500:560] += rng.integers(0, 40, 60)
    sparse[8191] = 9000
    frames = [(sparse, settings(0)), (np.zeros(8192, np.int64), settings(0))]
    got = packetize(frames, index_bits=13, seed=1, gaps=False)
    assert got == model(frames)
    assert len(got) < 8


def _window(byte_counts):
    # 128 bins whose tokens (no empty bins) are 1 byte (count 1) or 2 bytes (count 100).
    return [1 if size == 1 else 100 for size in byte_counts]


def test_choice_at_its_boundary():
    # A window of 128 bins goes compact when 10 + tokens < 8 + 256: 253 token bytes are
    # compact, 254 full. The tokens here: count 1 takes one byte, count 100 two.
    compact = _window([2] * 125 + [1] * 3)      # 253 bytes
    full = _window([2] * 126 + [1] * 2)         # 254 bytes
    frames = [(np.array(compact + full), settings(5, 0)),
              (np.array(full + compact), settings(5, 0))]
    got = packetize(frames, seed=3)
    assert got == model(frames)
    assert [(type, length) for type, length, _ in got] == [
        (PacketType.HISTOGRAM_COMPACT.value, 10 + 253), (PacketType.HISTOGRAM.value, 8 + 256),
        (PacketType.HISTOGRAM.value, 8 + 256), (PacketType.HISTOGRAM_COMPACT.value, 10 + 253)]


@pytest.mark.parametrize("lead,chunks", [(3, 1), (2, 2)])
def test_compact_chunk_fills_to_the_byte(lead, chunks):
    # Window one: 128 counts of 1 (128 token bytes). Window two: `lead` empty bins (one skip
    # token) and counts of 1: 126 bytes with three empty bins, so 128 + 126 = COMPACT_BYTES
    # fits one chunk; 127 bytes with two does not, and a second chunk starts.
    second = [0] * lead + [1] * (128 - lead)
    frames = [(np.array([1] * 128 + second), settings(5, 0))]
    got = packetize(frames, seed=4)
    assert got == model(frames)
    assert [type for type, _, _ in got] == [PacketType.HISTOGRAM_COMPACT.value] * chunks
    if chunks == 1:
        assert got[0][1] == 10 + 254


@pytest.mark.parametrize("shift,pixel_bits", [(0, 0), (5, 0), (7, 2), (12, 0), (13, 0), (9, 3)])
def test_full_packetizer_sends_full_chunks(shift, pixel_bits):
    # The small builds' packetizer: every frame as HISTOGRAM chunks of 128 bins at most, as the
    # model sends them with full_readout, whatever full_readout says.
    rng = np.random.default_rng(shift)
    bins = frame_bins(shift, pixel_bits)
    frames = [(random_frame(rng, shift, pixel_bits, density), settings(shift, pixel_bits, 3))
              for density in ((0.5,) if bins > 1024 else (0.01, 1))]
    got = packetize(frames, seed=shift, block=FullHistogramPacketizer)
    assert got == model(frames, full=True)


@pytest.mark.parametrize("block", [HistogramPacketizer, FullHistogramPacketizer])
def test_index_width_is_checked(construction_error, block):
    assert construction_error(lambda: block(index_bits=17)) == \
        "Index width must be an integer from 1 to 16 bits, not 17"


def test_settings_change_right_after_a_frame():
    # Frames of one bin and frames of other splits back to back, without gaps: each chunk
    # carries its own frame's settings, although they change as soon as its bin is taken.
    rng = np.random.default_rng(8)
    frames = [(np.array([5]), settings(13)),
              (random_frame(rng, 10, 6, 0.05), settings(10, 6)),
              (np.array([7]), settings(13, 0, 9)),
              (np.array([0, 3]), settings(12, 0, 1, full_readout=1)),
              (random_frame(rng, 12, 1, 0.5), settings(12, 1, 62))]
    got = packetize(frames, seed=8, gaps=False)
    assert got == model(frames)
