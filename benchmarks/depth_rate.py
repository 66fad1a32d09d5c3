"""Depth frames per second: 64 pixels, DEPTH packets against HISTOGRAM readout of the same frames.

For each split of the bank into 64 pixels (16, 128 and 1024 bins each), the script

* measures, in Amaranth's simulator, the cycles the :class:`~fliss.hdl.depth.engine.DepthEngine` takes
  from a frame's first bin to its packet's first beat, fed as the histogram readout feeds it
  (one bin every ``READOUT_CYCLES_PER_BIN`` cycles), and checks its packet against the model;
* takes the exact bytes on the wire of that DEPTH packet (COBS, CRC, delimiter; 10-bit
  characters) and of the HISTOGRAM chunks of the same frame (the baseline);
* prints frames per second at 3 and 12 Mbaud at 80 MHz. The engine holds the readout while its
  packet goes out, so a depth frame takes the engine's cycles plus the packet's line time; a
  histogram frame takes the longer of its readout and its chunks' line time.

The issue asks for at least 100 depth frames per second for 64 pixels at 3 Mbaud.

Usage: python benchmarks/depth_rate.py [--seed S]
"""

import argparse

import numpy as np

from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.hdl.depth.engine import DepthEngine
from fliss.hdl.event import TIMESTAMP_BITS
from fliss.hdl.histogram.engine import READOUT_CYCLES_PER_BIN
from fliss.hdl.protocol import PacketType, HistogramChunk, CHUNK_BINS, HISTOGRAM_COUNT_BITS
from fliss.protocol.frames import encode_frame
from fliss.protocol.layout import pack, pack_words
from fliss.sim.models.depth import depth_frame
from fliss.protocol.depth import depth_payload
from amaranth.sim import Simulator


PIXEL_BITS = 6
CHARACTER_BITS = 10
BAUDS = (3_000_000, 12_000_000)
SETTINGS = dict(filter=4, threshold=20)


def synthetic_frame(rng, bins):
    x = np.arange(bins) + 0.5
    centres = rng.uniform(0, bins, 1 << PIXEL_BITS)
    rate = 3 + 400 * np.exp(-0.5 * ((x[None] - centres[:, None]) / 1.5) ** 2)
    return np.minimum(rng.poisson(rate), 65535)


def engine_cycles(counts, shift):
    """Cycles from the first bin to the packet's first beat, and the packet's payload."""
    dut = DepthEngine(index_bits=16)
    flat = counts.reshape(-1)
    result = {}

    async def bench(ctx):
        ctx.set(dut.shift, shift)
        ctx.set(dut.pixel_bits, PIXEL_BITS)
        ctx.set(dut.settings.filter, SETTINGS["filter"])
        ctx.set(dut.settings.threshold, SETTINGS["threshold"])
        cycles = 0
        for index, count in enumerate(flat):
            ctx.set(dut.readout.valid, 1)
            ctx.set(dut.readout.p.index, index)
            ctx.set(dut.readout.p.count, int(count))
            ctx.set(dut.readout.p.last, index == len(flat) - 1)
            while True:
                _, _, ready = await ctx.tick().sample(dut.readout.ready)
                cycles += 1
                if ready:
                    break
            ctx.set(dut.readout.valid, 0)
            await ctx.tick().repeat(READOUT_CYCLES_PER_BIN - 1)
            cycles += READOUT_CYCLES_PER_BIN - 1
        ctx.set(dut.packets.ready, 1)
        payload = bytearray()
        while True:
            _, _, valid, beat = await ctx.tick().sample(dut.packets.valid, dut.packets.p)
            if valid and beat.first:
                result.setdefault("cycles", cycles)
            elif valid:
                payload.append(beat.data)
                if beat.last:
                    break
            cycles += 1
        result["payload"] = bytes(payload)

    sim = Simulator(dut)
    sim.add_clock(1 / DEFAULT_CLOCK_HZ)
    sim.add_testbench(bench)
    sim.run()
    return result["cycles"], result["payload"]


def line_seconds(frames, baud):
    return sum(len(frame) for frame in frames) * CHARACTER_BITS / baud


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    print(f"64 pixels, {DEFAULT_CLOCK_HZ / 1e6:.0f} MHz, filter {SETTINGS['filter']} bins; "
          f"histogram readout {READOUT_CYCLES_PER_BIN} cycles per bin")
    print(f"{'bins/pixel':>10} {'engine cycles':>13} {'DEPTH bytes':>11} {'HISTOGRAM bytes':>15}"
          + "".join(f" {f'depth/s @{b // 10**6}M':>13} {f'hist/s @{b // 10**6}M':>12}"
                    for b in BAUDS))
    slowest = float("inf")
    for shift in (9, 6, 3):
        bins = 1 << (TIMESTAMP_BITS - shift)
        counts = synthetic_frame(rng, bins)
        cycles, payload = engine_cycles(counts, shift)
        records = depth_frame(counts, shift=shift, **SETTINGS)
        expected = depth_payload(records, frame=0, first_pixel=0, pixel_bits=PIXEL_BITS,
                                 shift=shift, **SETTINGS)
        assert payload == expected, "the engine's packet differs from the model's"
        depth_wire = [encode_frame(PacketType.DEPTH, 0, payload)]
        flat = counts.reshape(-1)
        histogram_wire = [
            encode_frame(PacketType.HISTOGRAM, k % 256, pack(
                HistogramChunk, frame=0, first_bin=first, shift=shift,
                last=int(first + CHUNK_BINS >= len(flat))) +
                pack_words(flat[first:first + CHUNK_BINS], HISTOGRAM_COUNT_BITS))
            for k, first in enumerate(range(0, len(flat), CHUNK_BINS))]
        readout_s = READOUT_CYCLES_PER_BIN * len(flat) / DEFAULT_CLOCK_HZ
        row = f"{bins:>10} {cycles:>13} {len(depth_wire[0]):>11} " \
              f"{sum(map(len, histogram_wire)):>15}"
        for baud in BAUDS:
            depth_rate = 1 / (cycles / DEFAULT_CLOCK_HZ + line_seconds(depth_wire, baud))
            histogram_rate = 1 / max(readout_s, line_seconds(histogram_wire, baud))
            row += f" {depth_rate:>13.0f} {histogram_rate:>12.1f}"
            if baud == BAUDS[0]:
                slowest = min(slowest, depth_rate)
        print(row)
    print("(depth frames: engine cycles plus the DEPTH frame's line time; histogram frames: "
          "the longer of readout and line time of its chunks)")
    print(f"goal: at least 100 depth frames/s for 64 pixels at 3 Mbaud: slowest split "
          f"{slowest:.0f}/s: {'met' if slowest >= 100 else 'NOT met'}")


if __name__ == "__main__":
    main()
