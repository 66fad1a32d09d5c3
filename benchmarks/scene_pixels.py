"""Cost of the pixel-array scene: the line scene's 60 pixels against one pixel, on one core.

Prints, measured in the same run, for the paper's set-up (victim with FLISS at 1 MHz, a flash
aggressor 75 ns later at its effective PRF, background, dead time):

* the single-pixel scene (the baseline) and the 60-pixel line scene with each sensor kind, in
  chunks of laser cycles as :func:`fliss.sim.scene.acquire` runs them: laser cycles per second,
  and the time to simulate one frame of ``--integration`` (10 ms: 10 000 laser cycles);
* the same stepped one laser cycle at a time, as the virtual board's closed loop does: time
  per laser cycle.

Usage: ``python benchmarks/scene_pixels.py [--cycles N] [--repeat R] [--integration S]``
"""

import argparse
import math
import time

import numpy as np

from fliss.sim.models import scheduler
from fliss.sim.models.delay import DelayMode
from fliss.sim.scene import Aggressor, Scene, line_pixels, simulation_for


def scenes():
    victim = scheduler.Settings(mode=DelayMode.MASKED, mask_width=6, period=80)
    aggressor = Aggressor(period_cycles=80 + 31.5, offset_s=75e-9, detections_per_pulse=0.01)
    base = Scene(victim=victim, detections_per_pulse=0.05, background_hz=1e4,
                 aggressors=(aggressor,))
    return {"one pixel": base,
            "60 pixels, column": base.replace(pixels=line_pixels(sensor="column")),
            "60 pixels, per_pixel": base.replace(pixels=line_pixels(sensor="per_pixel"))}


def chunked(scene, cycles):
    simulation = simulation_for(scene, seed=1)
    for _ in simulation.chunks(cycles):
        pass


def closed_loop(scene, cycles):
    # As the virtual board: starts fed one by one, one laser cycle simulated per step.
    simulation = simulation_for(scene.replace(victim=scheduler.Settings(period=80)), seed=1,
                                chunk_cycles=64, external_starts=True)
    simulation.feed(100 + 80 * np.arange(cycles + 1))
    for _ in range(cycles):
        simulation.step(1)


def best_time(function, repeat):
    best = math.inf
    for _ in range(repeat):
        start = time.perf_counter()
        function()
        best = min(best, time.perf_counter() - start)
    return best


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cycles", type=int, default=200_000, help="laser cycles, chunked")
    parser.add_argument("--loop-cycles", type=int, default=2_000,
                        help="laser cycles, one per step")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--integration", type=float, default=10e-3,
                        help="frame integration time, s (1 MHz laser)")
    args = parser.parse_args(argv)
    frame_cycles = args.integration * 1e6
    print(f"{'scene':<24} {'cycles/s':>12} {'ms per frame':>13} {'us per cycle, loop':>19}")
    baseline = None
    for name, scene in scenes().items():
        seconds = best_time(lambda scene=scene: chunked(scene, args.cycles), args.repeat)
        loop = best_time(lambda scene=scene: closed_loop(scene, args.loop_cycles), args.repeat)
        rate = args.cycles / seconds
        per_cycle_us = loop / args.loop_cycles * 1e6
        baseline = baseline or (rate, per_cycle_us)
        print(f"{name:<24} {rate:12.3g} {frame_cycles / rate * 1e3:13.1f} "
              f"{per_cycle_us:19.0f}   (x{baseline[0] / rate:.1f}, x"
              f"{per_cycle_us / baseline[1]:.1f} the single pixel)")


if __name__ == "__main__":
    main()
