"""The depth engine in Amaranth's simulator against its model (bit for bit), and the model
against the physics of synthetic histograms (peaks at known positions, known background)."""

import random

import numpy as np
import pytest

from fliss.hdl.depth.engine import DepthEngine
from fliss.hdl.divider import SerialDivider
from fliss.hdl.protocol import (PacketType, DepthHeader, DepthRecord, DEPTH_HEADER_BYTES,
                                DEPTH_RECORD_BYTES, MAX_PAYLOAD, Nak, NakCode, registers_layout)
from fliss.hdl.registers import BY_NAME
from fliss.hdl.top import FlissTop, SMALL
from fliss.protocol.layout import pack, unpack, unpack_from
from fliss.sim.models.command import CommandModel
from fliss.protocol.depth import BACKGROUND_MAX, check_depth_settings
from fliss.sim.models.depth import depth_frame
from fliss.protocol.depth import depth_payload, unpack_depth
from simulation import simulate


def run_engine(frames, *, seed=0, idle=0.3, index_bits=13):
    """Feed ``frames`` (dicts: counts (P, N), shift, pixel_bits, first_pixel, filter,
    threshold) through a :class:`DepthEngine`; return its packets as (type, length, payload)
    and the cycles from each frame's first bin to its packet's last byte."""
    dut = DepthEngine(index_bits=index_bits)
    rng = random.Random(seed)
    packets = []
    starts, ends = [], []

    async def source(ctx):
        for frame in frames:
            counts = np.asarray(frame["counts"])
            flat = counts.reshape(-1)
            ctx.set(dut.shift, frame["shift"])
            ctx.set(dut.pixel_bits, frame["pixel_bits"])
            ctx.set(dut.first_pixel, frame["first_pixel"])
            ctx.set(dut.settings.filter, frame["filter"])
            ctx.set(dut.settings.threshold, frame["threshold"])
            for index, count in enumerate(flat):
                ctx.set(dut.readout.valid, 1)
                ctx.set(dut.readout.p.index, index)
                ctx.set(dut.readout.p.count, int(count))
                ctx.set(dut.readout.p.last, index == len(flat) - 1)
                if index == 0:
                    starts.append(ctx.get(cycle_count[0]))
                await ctx.tick().until(dut.readout.ready)
                ctx.set(dut.readout.valid, 0)
                if rng.random() < idle:
                    await ctx.tick().repeat(rng.randrange(1, 4))
                # the settings may change once the frame's first bin is in
                ctx.set(dut.settings.filter, rng.randint(1, 16))
                ctx.set(dut.settings.threshold, rng.randrange(1 << 16))
        while len(packets) < len(frames):
            await ctx.tick()

    cycle_count = [0]

    async def clock(ctx):
        while True:
            await ctx.tick()
            cycle_count[0] += 1

    async def sink(ctx):
        payload = bytearray()
        while True:
            ready = rng.random() < (1 - idle)
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
                    ends.append(cycle_count[0])
            await ctx.tick()

    # (the cycle counter is kept in Python: the testbench reads it as a list)
    cycle_count = [0]
    simulate(dut, source, background=[sink, clock], clock_hz=100e6)
    return packets, [end - start for start, end in zip(starts, ends)]


def model_payload(frame, number):
    records = depth_frame(frame["counts"], shift=frame["shift"], filter=frame["filter"],
                          threshold=frame["threshold"])
    return depth_payload(records, frame=number, first_pixel=frame["first_pixel"],
                         pixel_bits=frame["pixel_bits"], shift=frame["shift"],
                         filter=frame["filter"], threshold=frame["threshold"])


def synthetic(rng, pixels, bins, *, centres=None, sigma=1.0, amplitude=200.0,
              background=2.0):
    """Poisson histograms of Gaussian peaks at ``centres`` (in bins, bin j spanning [j, j+1))
    on a flat background; returns the counts (P, N) and the centres."""
    if centres is None:
        centres = rng.uniform(0, bins, pixels)
    x = np.arange(bins) + 0.5
    rate = background + amplitude * np.exp(-0.5 * ((x[None] - np.asarray(centres)[:, None])
                                                    / sigma) ** 2)
    return np.minimum(rng.poisson(rate), 65535), np.asarray(centres)


def frame_of(counts, shift, **settings):
    pixels = len(counts)
    return dict(counts=counts, shift=shift, pixel_bits=pixels.bit_length() - 1,
                first_pixel=settings.pop("first_pixel", 0), **settings)


def check_engine(frames, **options):
    packets, cycles = run_engine(frames, **options)
    assert len(packets) == len(frames)
    for number, ((type_, length, payload), frame) in enumerate(zip(packets, frames)):
        assert type_ == PacketType.DEPTH.value
        expected = model_payload(frame, number)
        assert length == len(payload) == len(expected)
        assert payload == expected, f"frame {number}: {unpack_depth(payload)} != " \
                                    f"{unpack_depth(expected)}"
    return cycles


# Gateware against the model

@pytest.mark.parametrize("filter", [1, 3, 4, 16])
def test_engine_matches_model_on_peaks(filter):
    rng = np.random.default_rng(filter)
    frames = []
    for shift, pixels in ((7, 8), (8, 16), (10, 4)):
        bins = 8192 >> shift
        counts, _ = synthetic(rng, pixels, bins, sigma=rng.uniform(0.5, 3),
                              amplitude=rng.uniform(5, 500), background=rng.uniform(0, 20))
        frames.append(frame_of(counts, shift, filter=filter, threshold=int(rng.integers(0, 300)),
                               first_pixel=int(rng.integers(0, 64 - pixels + 1))))
    check_engine(frames, seed=filter)


def test_engine_edge_cases():
    # Peaks at bin 0 and at the last bin, a flat histogram, all zero, saturated counts, a filter
    # as wide as the pixel and wider, a pixel of one bin, ties.
    n = 32                                          # shift 8
    peak_first = np.full(n, 3)
    peak_first[0] = 900
    peak_last = np.full(n, 3)
    peak_last[-1] = 900
    tie = np.zeros(n, int)
    tie[[5, 6, 20, 21]] = 40
    rising = np.arange(n) * 2000
    counts = np.array([peak_first, peak_last, np.full(n, 7), np.zeros(n, int),
                       np.full(n, 65535), tie, rising, np.where(np.arange(n) % 2, 65535, 0)])
    frames = [frame_of(counts, 8, filter=f, threshold=t) for f, t in
              ((1, 0), (16, 16), (2, 65535), (5, 100))]
    frames.append(frame_of(np.array([[5, 9, 2, 0, 65535, 1, 1, 1]] * 2), 10, filter=16,
                           threshold=3))            # W = N = 8
    frames.append(frame_of(np.array([[7]] * 64), 13, filter=4, threshold=7,
                           first_pixel=0))          # one bin per pixel, 64 pixels
    check_engine(frames, seed=3)


def test_engine_one_pixel_many_bins_and_back_to_back():
    # One pixel of 1024 bins (shift 3), then frames with no gaps and a consumer always ready.
    rng = np.random.default_rng(7)
    frames = []
    for shift, pixels in ((3, 1), (9, 64), (11, 2)):
        counts, _ = synthetic(rng, pixels, 8192 >> shift, sigma=2.0, amplitude=60)
        frames.append(frame_of(counts, shift, filter=6, threshold=20))
    cycles = check_engine(frames, seed=5, idle=0.0)
    # Per pixel: W + 72 cycles of arithmetic plus 6 of pipeline and storing; per frame the
    # header, 9 cycles per record sent, and one cycle per bin.
    assert cycles[1] >= 64 * 16 + 64 * 7


def test_engine_refuses_bad_parameters(construction_error):
    assert construction_error(lambda: DepthEngine(index_bits=12)) == \
        "Index width must be an integer from 13 to 32 bits, not 12"
    assert construction_error(lambda: SerialDivider(8, 0, 4)) == \
        "Divisor width must be a positive integer, not 0"


@pytest.mark.parametrize("seed", range(3))
def test_divider_matches_python(seed):
    rng = random.Random(seed)
    cases = [(0, 1), (1, 0), ((1 << 20) * 5 - 1, 5), (123456789, 8191), (7, 7)]
    for _ in range(30):             # the quotient fits 20 bits, the dividend 33
        divisor = rng.randrange(1, 1 << rng.randint(1, 21))
        quotient = rng.randrange(min(1 << 20, ((1 << 33) - divisor) // divisor))
        cases.append((quotient * divisor + rng.randrange(divisor), divisor))
    dut = SerialDivider(33, 21, 20)
    results = []

    async def bench(ctx):
        for dividend, divisor in cases:
            ctx.set(dut.dividend, dividend)
            ctx.set(dut.divisor, divisor)
            ctx.set(dut.start, 1)
            await ctx.tick()
            ctx.set(dut.start, 0)
            await ctx.tick().until(~dut.busy)
            results.append((ctx.get(dut.quotient), ctx.get(dut.remainder)))

    simulate(dut, bench)
    for (dividend, divisor), (quotient, remainder) in zip(cases, results):
        if divisor:
            assert (quotient, remainder) == divmod(dividend, divisor)
        else:
            assert quotient == (1 << 20) - 1


# The model against the physics

def test_model_finds_true_peak_and_background():
    rng = np.random.default_rng(11)
    bins = 256
    centres = rng.uniform(20, bins - 20, 64)
    counts, centres = synthetic(rng, 64, bins, centres=centres, sigma=1.5, amplitude=400,
                                background=5.0)
    records = depth_frame(counts, shift=5, filter=4, threshold=50)
    position = records["position"] / 16
    assert np.all(records["detected"])
    assert np.max(np.abs(position - centres)) < 0.25
    # the background is the mean outside the 4-bin window: 5 counts plus the peak's tails
    # beyond +-2 bins (erfc(2 / (1.5 sqrt 2)) = 18.2 % of its 400 sqrt(2 pi) 1.5 counts) spread
    # over the other 252 bins
    area = 400 * np.sqrt(2 * np.pi) * 1.5
    tails = area * 0.182 / (bins - 4)
    assert abs(np.mean(records["background"] / 16) - (5.0 + tails)) < 0.1
    assert np.all(np.abs(records["background"] / 16 - (5.0 + tails)) < 0.6)
    # height: the peak's counts inside the window (81.8 % of its area), less nothing else
    assert abs(np.median(records["height"]) - 0.818 * area) < 0.05 * area


def test_model_sub_bin_position_of_a_noiseless_peak():
    # A symmetric peak centred between bins k and k+1 (W = 2): the interpolation puts it exactly
    # at the boundary; shifted by a quarter bin the parabola moves it the same way.
    counts = np.zeros((2, 64), int)
    counts[0, 30:32] = 100
    counts[0, [29, 32]] = 40
    counts[1, 30] = 100
    counts[1, 31] = 60
    counts[1, 29] = 30
    records = depth_frame(counts, shift=7, filter=2, threshold=1)
    assert records["position"][0] == 31 * 16
    assert 30.5 * 16 < records["position"][1] < 31 * 16
    assert records["background"][0] == (80 * 16) // 62


def test_model_edge_cases():
    n = 16
    flat = depth_frame(np.full((1, n), 9), shift=9, filter=4, threshold=1)
    assert flat["height"][0] == 0 and not flat["detected"][0]
    assert flat["background"][0] == 9 * 16
    assert flat["position"][0] == 2 * 16            # the first window: centre of bins 0-3
    zero = depth_frame(np.zeros((1, n), int), shift=9, filter=4, threshold=0)
    assert (zero["height"][0], zero["background"][0], zero["detected"][0]) == (0, 0, True)
    full = depth_frame(np.full((1, n), 65535), shift=9, filter=16, threshold=0)
    assert full["height"][0] == 16 * 65535 and full["background"][0] == 0
    saturated = depth_frame(np.full((1, n), 65535), shift=9, filter=1, threshold=0)
    assert saturated["background"][0] == BACKGROUND_MAX
    edge = np.zeros((2, n), int)
    edge[0, 0] = edge[1, -1] = 50
    records = depth_frame(edge, shift=9, filter=1, threshold=50)
    assert list(records["position"]) == [8, (n - 1) * 16 + 8]
    assert list(records["height"]) == [50, 50] and all(records["detected"])


def test_model_refusals():
    with pytest.raises(ValueError, match="Depth filter must be an integer from 1 to 16, not 17"):
        check_depth_settings(shift=0, filter=17, threshold=0)
    with pytest.raises(ValueError, match=r"Counts must have shape \(1 to 64 pixels, 8 bins\) "
                                         r"for bin shift 10, not \(2, 9\)"):
        depth_frame(np.zeros((2, 9), int), shift=10, filter=1, threshold=0)
    with pytest.raises(ValueError, match="Counts must be from 0 to 65535"):
        depth_frame(np.full((1, 8), 65536), shift=10, filter=1, threshold=0)
    with pytest.raises(ValueError, match="First pixel 40 plus 32 pixels is beyond the 64"):
        check_depth_settings(shift=0, filter=1, threshold=0, pixel_bits=5, first_pixel=40)


# The payload

def test_payload_packs_with_the_layouts_and_fits():
    records = depth_frame(np.arange(64 * 128).reshape(64, 128) % 977, shift=6, filter=5,
                          threshold=9)
    payload = depth_payload(records, frame=5, first_pixel=0, pixel_bits=6, shift=6, filter=5,
                            threshold=9)
    assert len(payload) == DEPTH_HEADER_BYTES + 64 * DEPTH_RECORD_BYTES == MAX_PAYLOAD
    head, unpacked = unpack_depth(payload)
    assert head == dict(frame=5, first_pixel=0, pixel_bits=6, shift=6, filter=5, threshold=9)
    assert np.array_equal(unpacked, records)
    # every record reads back through the codec's layout reader too
    for k in (0, 17, 63):
        value = unpack_from(DepthRecord, payload, DEPTH_HEADER_BYTES + k * DEPTH_RECORD_BYTES)
        assert value["position"] == records["position"][k]
        assert value["background"] == records["background"][k]
    assert payload[:DEPTH_HEADER_BYTES] == pack(DepthHeader, frame=5, pixel_bits=6, shift=6,
                                                filter=5, threshold=9)


@pytest.mark.parametrize("payload, message", [
    (b"\x00" * 5, "shorter than its 10-byte header"),
    (pack(DepthHeader, pixel_bits=1) + bytes(7), "DEPTH payload of 17 bytes, not 24 for 2"),
    (pack(DepthHeader, pixel_bits=7), "DEPTH header out of range: 7 pixel bits"),
    (pack(DepthHeader, pixel_bits=2, first_pixel=62), "DEPTH header out of range"),
])
def test_unpack_refuses_malformed(payload, message):
    with pytest.raises(ValueError, match=message):
        unpack_depth(payload)


def test_builds_without_the_engine_refuse_depth_mode(construction_error):
    assert "acquisition" not in FlissTop().register_maxima()
    maxima = FlissTop(depth=False).register_maxima()
    small = FlissTop(**SMALL).register_maxima()
    # (its settings stay, as wide as their resets need: 4 in 3 bits, 16 in 5)
    # (and, as in every build without the fine TDC, tdc_source up to 1 and its registers 0)
    fine = {"tdc_source": 1, "fine_lsb": 0, "tdc_input": 0, "table_address": 0, "table_data": 0}
    assert maxima == {"acquisition": 1, "depth_filter": 0b111, "depth_threshold": 0b11111,
                      **fine}
    assert small["acquisition"] == 0
    assert construction_error(lambda: FlissTop(depth="yes"), TypeError) == \
        "depth must be True or False, not 'yes'"
    # the command processor's model (held to the gateware by its tests) refuses mode 2
    model = CommandModel(80_000_000, 3_000_000, maxima=maxima)
    address = BY_NAME["acquisition"].address
    reply = model.command(PacketType.WRITE.value, 4,
                          pack(registers_layout(1), address=address, values=[2]), None)
    assert reply[0] == PacketType.NAK
    assert unpack(Nak, reply[1]) == dict(seq=4, code=NakCode.OUT_OF_RANGE.value, detail=address)
