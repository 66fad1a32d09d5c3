"""The fine TDC's figures from its model (docs/finetdc.md, "The model and its figures").

For model lines in two builds: one line of 640 taps (the baseline: the ``CCU2C`` cell model's
21.5 ps taps with 5 ps of random variation; the same with 30 ps more at every eighth tap, a hop
between logic tiles; nextpnr's routed line, taps of 8.4 and 62.5 ps in turn with 20 ps of
variation), and two lines of 400 taps summed (the gateware's: nextpnr's taps with 20 and 5 ps of
variation, the second line a random phase after the first; the two in step with no
variation; and the cell model's taps, with which the lines are shorter than a period): the mean code width and the mean width of the code a hit falls in, DNL and INL of
the raw codes, each raw code's error against the truth with the reset table's times and
calibrated, DNL and INL of the calibrated 50 ps timestamps, and the single-shot RMS error over
``--hits`` hits (calibration from 2**22 other hits). Then the two-line TDC after a change of
temperature with the table left as it was. Then the scene simulator's photons (a target at 4 m
and an aggressor 75 ns later, FLISS off and on) through the modelled lines: the strongest
peak's ToF and FWHM against the scene's truth, from the paper's 50 ps sensor, the fine TDC at 50
and 12.5 ps, and the coarse TDC.

Usage: python benchmarks/finetdc.py [--hits 1000000] [--seed 0] [--no-scene]
"""

import argparse
import time

import numpy as np

from fliss.sim.models.finetdc import Line
from fliss.sim.studies.finetdc import evaluate, scene_comparison, temperature_drift


#: nextpnr's routed ULX3S line (benchmarks/finetdc_chain.py): 8.4 ps within a cell, 62.5 ps to
#: the next
NEXTPNR = dict(tap_s=8.4e-12, hop_taps=2, hop_s=54.1e-12)
#: The one-line build: 640 taps; its reset table took every code as 21.5 ps
ONE_LINE = dict(taps=640, lines=1)
#: name -> (line, the reset table's code width or None for the gateware's)
LINES = {
    "1 x 640, cell model, 5 ps": (Line(**ONE_LINE, tap_s=21.5e-12, hop_s=0.0), 21.5e-12),
    "1 x 640, + 30 ps every 8th": (Line(**ONE_LINE, tap_s=21.5e-12, hop_taps=8, hop_s=30e-12),
                                   21.5e-12),
    "1 x 640, nextpnr's, 20 ps": (Line(**ONE_LINE, **NEXTPNR, sigma_s=20e-12), 21.5e-12),
    "2 x 400, nextpnr's, 20 ps": (Line(**NEXTPNR, sigma_s=20e-12), None),
    "2 x 400, nextpnr's, 5 ps": (Line(**NEXTPNR, sigma_s=5e-12), None),
    "2 x 400, in step, 0 ps": (Line(**NEXTPNR, sigma_s=0.0, phase_s=0.0), None),
    "2 x 400, cell model, 5 ps": (Line(tap_s=21.5e-12, hop_s=0.0), None),
}
#: Delay change per kelvin (see docs/finetdc.md#temperature) and temperature changes, K
COEFFICIENTS_PER_K = (1e-3, 4e-3)
DTS_K = (0.25, 0.5, 1, 2, 5, 10)


def lines(hits, seed):
    print("line                       | code ps (hit's) | DNL raw | INL raw | code error ps reset/"
          "calibrated | DNL/INL 50 ps after | RMS ps reset | RMS ps after (12.5 / 50 ps LSB)")
    for name, (line, nominal) in LINES.items():
        options = {} if nominal is None else {"nominal_code_s": nominal}
        fine = evaluate(line, test_hits=hits, lsb_select=2, seed=seed, **options)
        coarse = evaluate(line, test_hits=hits, lsb_select=0, seed=seed, **options)
        code = fine["mean_code_s"]
        after = np.abs(fine["code_inl_after_s"]).max()
        print(f"{name:<26} | {code * 1e12:5.2f} ({fine['weighted_code_s'] * 1e12:4.1f}) | "
              f"{np.abs(fine['dnl_before']).max():7.2f} | "
              f"{np.abs(fine['inl_before']).max():7.2f} | "
              f"{np.abs(fine['code_inl_before_s']).max() * 1e12:6.1f} / {after * 1e12:4.1f} "
              f"({after / code:.2f} code) | {np.abs(fine['dnl_after']).max():.2f} / "
              f"{np.abs(fine['inl_after']).max():.2f} | {fine['rms_before_s'] * 1e12:12.1f} | "
              f"{fine['rms_after_s'] * 1e12:.1f} / {coarse['rms_after_s'] * 1e12:.1f}"
              + (f"  (hits past every tap: {fine['full_share']:.1%})" if fine["full_share"]
                 else ""))


def drift(hits, seed):
    line = LINES["2 x 400, nextpnr's, 20 ps"][0]
    print("delay change | dT K | shift ps | worst code ps | RMS ps | RMS ps, shift taken off "
          "(12.5 ps LSB)")
    for coefficient in COEFFICIENTS_PER_K:
        for row in temperature_drift(line, coefficient_per_k=coefficient, dts_k=(0, *DTS_K),
                                     test_hits=hits, seed=seed):
            print(f"{coefficient * 100:6.1f} %/K | {row['dt_k']:4g} | "
                  f"{row['shift_s'] * 1e12:8.1f} | {row['worst_s'] * 1e12:13.1f} | "
                  f"{row['rms_s'] * 1e12:6.1f} | {row['rms_centred_s'] * 1e12:.1f}")


def scene(seed):
    print("FLISS | readout        | ToF ns (truth) | ToF error ps | FWHM ns (truth) | peaks")
    for row in scene_comparison(seed=seed):
        print(f"{row['fliss']:<5} | {row['readout']:<14} | {row['tof_s'] * 1e9:6.3f} "
              f"({row['truth_tof_s'] * 1e9:.3f}) | "
              f"{(row['tof_s'] - row['truth_tof_s']) * 1e12:12.0f} | "
              f"{row['fwhm_s'] * 1e9:6.3f} ({row['truth_fwhm_s'] * 1e9:.3f}) | {row['peaks']}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--hits", type=int, default=10 ** 6, help="test hits per line")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-scene", action="store_true", help="leave the scene out")
    args = parser.parse_args()
    started = time.monotonic()
    lines(args.hits, args.seed)
    print()
    drift(args.hits, args.seed)
    if not args.no_scene:
        print()
        scene(args.seed)
    print(f"\n{time.monotonic() - started:.0f} s")


if __name__ == "__main__":
    main()
