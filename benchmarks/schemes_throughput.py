"""Throughput of the schemes study's frame simulation (:mod:`fliss.sim.studies.schemes`), per
scheme, in the victim's laser cycles (TDC windows) per second on one core, with the detector's
effects off (the paper's preset) and on.

"Effects on" is a detector with every effect of :class:`fliss.sim.scene.Detector`: 1.4 %
afterpulsing (40 ns), 3.5 % orthogonal and 1 % diagonal crosstalk between the macro-pixel's
SPADs, a 10 % diffusion tail of 80 ps, 7 kHz dark counts, 20 ns dead time. Each scheme runs at
its sweep's settings (examples/schemes-full.toml) with one aggressor and ambient light of
1e5 /s; a 10 ms frame of a 1 MHz scheme is 10^4 laser cycles (7.2e3 with FLISS's mean period),
of a 10 kHz one 100. The figure is the simulation of the frame (photons, SPADs, gate, TDC,
histogram), not the peak finder that judges it. Best of ``--repeat`` runs of ``--frames``
frames, timed in the process's CPU time (``time.process_time``: per core, and less sensitive
than wall time to other jobs on a shared machine; a core's caches shared with them still slow
it).

Goal: at least 1e7 laser cycles per second per core with the effects on.

Usage: ``python benchmarks/schemes_throughput.py [--frames N] [--repeat R] [--cameras N]``
"""

import argparse
import time

import numpy as np

from fliss.hdl.event import TDC_LSB_S
from fliss.sim.scene import Detector
from fliss.sim.scene.description import time_of_flight
from fliss.sim.scene.presets import PRESETS
from fliss.sim.studies.schemes import check_point, pulses_per_frame
from fliss.sim.studies.schemes.frame import simulate_frame


SCHEMES = {
    "no scheme, 1 MHz": dict(scheme="none"),
    "PRF hopping": dict(scheme="hopping"),
    "code, 4 chips (multi-hit)": dict(scheme="code"),
    "FLISS mseq L=6": dict(scheme="fliss"),
    "FLISS masked Wm=6": dict(scheme="fliss", delay_mode="masked"),
    "coincidence 2 of 4, 10 kHz": dict(scheme="none", period_cycles=8000, spads=4,
                                       coincidence=2),
    "FLISS masked + coincidence 2 of 4, 10 kHz": dict(scheme="fliss", delay_mode="masked",
                                                      period_cycles=8000, spads=4,
                                                      coincidence=2),
}

EFFECTS = Detector(afterpulse_probability=0.014, afterpulse_s=(40e-9,),
                   crosstalk_orthogonal=0.035, crosstalk_diagonal=0.01, tail_fraction=0.1,
                   tail_s=80e-12, dark_count_hz=7e3)


def prepared(settings, cameras):
    point = check_point(dict(settings, cameras=cameras))
    return dict(point, _tof_lsb=time_of_flight(point["distance_m"]) / TDC_LSB_S,
                _detections_per_pulse=point["detections_per_frame"] / pulses_per_frame(point))


def rate(point, detector, frames, repeat):
    """Best laser cycles (TDC windows) per second over ``repeat`` runs of ``frames`` frames,
    and the simulated time per second of that run."""
    rng = np.random.default_rng(1)
    simulate_frame(point, detector, rng)            # caches (delay sequences) warm
    best = (0.0, 0.0)
    for _ in range(repeat):
        windows = 0
        start = time.process_time()
        for _ in range(frames):
            windows += simulate_frame(point, detector, rng).windows
        elapsed = time.process_time() - start
        best = max(best, (windows / elapsed, frames * point["t_int_s"] / elapsed))
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--cameras", type=int, default=2,
                        help="cameras of the frame, the victim's included (default 2)")
    args = parser.parse_args()
    print(f"{args.cameras} cameras, {args.frames} frames of 10 ms, best of {args.repeat}")
    print(f"{'scheme':45s} {'effects off':>14s} {'effects on':>14s}   (laser cycles/s)")
    for name, settings in SCHEMES.items():
        point = prepared(settings, args.cameras)
        off, off_real = rate(point, PRESETS["paper"], args.frames, args.repeat)
        on, on_real = rate(point, EFFECTS, args.frames, args.repeat)
        goal = "" if on >= 1e7 else "  below 1e7 with effects"
        print(f"{name:45s} {off:14.3g} {on:14.3g}   x{off_real:.0f} / x{on_real:.0f}{goal}")
    print("(x real time: simulated seconds a second, effects off / on)")


if __name__ == "__main__":
    main()
