"""Throughput of the scene simulator, in simulated laser cycles per second on one core.

Prints, measured in the same run:

* the scene simulator (:mod:`fliss.sim.scene`) on the paper's scene (victim with FLISS, an
  aggressor at its effective PRF, background, dead time, last-photon TDC), for three delay sources;
* baseline 1: one ``numpy`` Poisson draw per laser cycle (``rng.poisson(0.05, n)``), about the least
  any per-cycle Monte Carlo must do;
* baseline 2: the same physics written as a plain per-cycle Python loop, on fewer cycles.

Goal: at least 1e7 laser cycles per second per core.

Usage: ``python benchmarks/scene_throughput.py [--cycles N] [--repeat R]``
"""

import argparse
import math
import time

import numpy as np

from fliss.hdl.event import TDC_LSB_S
from fliss.sim.models import delay as delay_model
from fliss.sim.models import scheduler
from fliss.sim.scene import Aggressor, Scene, Simulation


def paper_scene(mode, **setting):
    victim = scheduler.Settings(mode=delay_model.parse_mode(mode), period=80, **setting)
    mean = float(delay_model.mean_delay(victim.mode, length=victim.length,
                                        mask_width=victim.mask_width))
    return Scene(victim=victim, aggressors=(Aggressor(period_cycles=80 + mean),))


def best_rate(function, cycles, repeat):
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return cycles / best


def simulate(scene, cycles):
    simulation = Simulation(scene, seed=1)
    for _ in simulation.chunks(cycles):
        pass


def python_loop(cycles, seed=1):
    """Baseline 2: the paper's scene (mseq L = 6), one laser cycle at a time."""
    rng = np.random.default_rng(seed)
    lsb = 250.0
    delays = delay_model.delays("mseq", cycles, length=6)
    starts = (scheduler.fire_cycles(delays, 80) + scheduler.LATENCY) * lsb
    sigma = math.hypot(2.1, 0.1) / 2.3548 / 0.05
    tof = 2 * 4.0 / 299_792_458 / TDC_LSB_S
    period = 111 * lsb
    offset = 75e-9 / TDC_LSB_S + tof + 2 * lsb
    dead = 20e-9 / TDC_LSB_S
    background = 1e5 * TDC_LSB_S
    histogram = np.zeros(8192, dtype=np.int64)
    last = -math.inf
    for start in starts:
        photons = [start + tof + sigma * rng.standard_normal()
                   for _ in range(rng.poisson(0.05))]
        j = math.ceil((start - dead - offset - 8 * sigma) / period)
        while offset + j * period < start + 8192 + 8 * sigma:
            photons += [offset + j * period + sigma * rng.standard_normal()
                        for _ in range(rng.poisson(0.05))]
            j += 1
        photons += list(start - dead + rng.uniform(0, 8192 + dead, rng.poisson(
            background * (8192 + dead))))
        kept = None
        for time_ in sorted(photons):
            if time_ < start - dead or time_ >= start + 8192 or time_ - last < dead:
                continue
            last = time_
            if time_ >= start:
                kept = time_
        if kept is not None:
            histogram[int(kept - start)] += 1
    return histogram


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cycles", type=int, default=4_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    cycles = args.cycles

    rng = np.random.default_rng(1)
    poisson = best_rate(lambda: rng.poisson(0.05, cycles), cycles, args.repeat)
    loop_cycles = 20_000
    loop = best_rate(lambda: python_loop(loop_cycles), loop_cycles, 1)

    print(f"laser cycles per second, one core ({cycles:,} cycles, best of {args.repeat})")
    print(f"  {'baseline: numpy Poisson draw per cycle':<52} {poisson:>14,.0f}")
    print(f"  {'baseline: per-cycle Python loop (20,000 cycles)':<52} {loop:>14,.0f}")
    for label, scene in (("scene, FLISS off, aggressor", paper_scene("off")),
                         ("scene, mseq L = 6, aggressor (paper)", paper_scene("mseq", length=6)),
                         ("scene, masked Wm = 6, aggressor (paper)",
                          paper_scene("masked", mask_width=6))):
        rate = best_rate(lambda scene=scene: simulate(scene, cycles), cycles, args.repeat)
        print(f"  {label:<52} {rate:>14,.0f}   {rate / poisson:5.2f}x Poisson draw, "
              f"{rate / loop:6.0f}x Python loop, goal 1e7: {'met' if rate >= 1e7 else 'NOT met'}")


if __name__ == "__main__":
    main()
