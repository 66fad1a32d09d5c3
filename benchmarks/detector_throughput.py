"""Throughput of the scene simulator with the detector's effects off and on, side by side.

Prints laser cycles per second on one core, measured in the same run, for the paper's scene
(victim with FLISS masked Wm = 6 at 1 MHz, an aggressor at its effective PRF, background
100 kHz, 20 ns dead time) with the default detector and with every effect of
:class:`fliss.sim.scene.Detector` on (PDP, dark counts with hot pixels, a diffusion tail,
afterpulsing with two exponentials, non-paralysable or paralysable dead time; crosstalk too
for the pixel array), for one pixel and for the paper's 60-pixel column; and one pixel in closed loop (TDC starts
fed one at a time, a step per laser cycle, as the virtual boards step it). Each figure is
measured ``--repeat`` times: minimum and median.

Goal: at least 1e7 laser cycles per second per core with every effect on (one pixel).

Usage: ``python benchmarks/detector_throughput.py [--cycles N] [--repeat R]``
"""

import argparse
import statistics
import time

from fliss.sim.models import delay as delay_model
from fliss.sim.models import scheduler
from fliss.sim.scene import Aggressor, Detector, Scene, line_pixels, simulation_for


def every_effect(paralysable):
    return Detector(pdp=0.5, dark_count_hz=1e3, dark_spread=0.5, hot_fraction=0.05,
                    hot_dark_count_hz=1e5, paralysable=paralysable, tail_fraction=0.2,
                    tail_s=0.5e-9, afterpulse_probability=0.02, afterpulse_s=(20e-9, 200e-9),
                    afterpulse_weights=(0.7, 0.3), crosstalk_orthogonal=0.01,
                    crosstalk_diagonal=0.002)


def paper_scene(detector=None, pixels=None):
    victim = scheduler.Settings(mode=delay_model.parse_mode("masked"), mask_width=6, period=80)
    mean = float(delay_model.mean_delay(victim.mode, length=victim.length,
                                        mask_width=victim.mask_width))
    options = dict(victim=victim, aggressors=(Aggressor(period_cycles=80 + mean),),
                   pixels=pixels, detector=detector)
    if pixels is not None:
        options.update(detections_per_pulse=0.02, background_hz=1e4)
    return Scene(**options)


def rates(scene, cycles, repeat):
    """Laser cycles per second of ``repeat`` runs of ``cycles`` cycles."""
    measured = []
    for _ in range(repeat):
        simulation = simulation_for(scene, seed=1)
        start = time.process_time()
        for _ in simulation.chunks(cycles):
            pass
        measured.append(cycles / (time.process_time() - start))
    return min(measured), statistics.median(measured)


def closed_loop(scene, cycles, repeat):
    """Laser cycles per second stepped one at a time with fed starts (80 clock cycles apart)."""
    measured = []
    for _ in range(repeat):
        simulation = simulation_for(scene, seed=1, chunk_cycles=64, external_starts=True)
        cycle = 2
        simulation.feed(cycle)
        start = time.process_time()
        for _ in range(cycles):
            cycle += 80
            simulation.feed(cycle)
            simulation.step(until_cycle=cycle)
        measured.append(cycles / (time.process_time() - start))
    return min(measured), statistics.median(measured)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cycles", type=int, default=2_000_000)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    column = line_pixels()
    cases = (("one pixel", None, args.cycles), ("60-pixel column", column, args.cycles // 20))
    print(f"laser cycles per second, one core (CPU time), min / median of {args.repeat}")
    print(f"  {'scene':<18} {'effects off':>25} {'every effect, non-par.':>25} "
          f"{'every effect, paralysable':>27}")
    for label, pixels, cycles in cases:
        figures = [rates(paper_scene(detector, pixels), cycles, args.repeat)
                   for detector in (None, every_effect(False), every_effect(True))]
        cells = [f"{low:11.3g} / {middle:9.3g}" for low, middle in figures]
        goal = "" if pixels is not None else \
            f"   goal 1e7 (every effect): {'met' if min(f[1] for f in figures[1:]) >= 1e7 else 'NOT met'}"
        print(f"  {label:<18} {cells[0]:>25} {cells[1]:>25} {cells[2]:>27}{goal}")
    loop = args.cycles // 20
    figures = [closed_loop(paper_scene(detector), loop, args.repeat)
               for detector in (None, every_effect(False), every_effect(True))]
    cells = [f"{low:11.3g} / {middle:9.3g}" for low, middle in figures]
    print(f"  {'closed loop':<18} {cells[0]:>25} {cells[1]:>25} {cells[2]:>27}")


if __name__ == "__main__":
    main()
