"""The fine TDC's figures from its model: the tables of docs/finetdc.md.

For three model lines (the ``CCU2C`` cell model's 21.5 ps taps with 5 ps of random variation;
the same with 30 ps more at every eighth tap, a hop between logic tiles; nextpnr's routed line,
taps of 8.4 and 62.5 ps in turn with 20 ps of variation): the mean tap width, DNL and INL
of the raw codes, each raw code's error against the truth with nominal and with calibrated
times, DNL and INL of the calibrated 50 ps timestamps, and the single-shot RMS error over
``--hits`` hits (calibration from 2**22 other hits). Then the scene simulator's photons (a
target at 4 m and an aggressor 75 ns later, FLISS off and on) through the modelled line: the
strongest peak's ToF and FWHM against the scene's truth, from the paper's 50 ps sensor, the
fine TDC at 50 and 12.5 ps, and the coarse TDC.

Usage: python benchmarks/finetdc.py [--hits 1000000] [--seed 0]
"""

import argparse
import time

import numpy as np

from fliss.sim.models.finetdc import Line
from fliss.sim.studies.finetdc import evaluate, scene_comparison


LINES = {"timing model, 5 ps sigma": Line(),
         "+ 30 ps every 8th tap": Line(tile_extra_s=30e-12),
         # nextpnr's routed ULX3S line (benchmarks/finetdc_chain.py): 8.4 ps within a cell,
         # 62.5 ps to the next, 39 ps of spread from the routes to the flip-flops
         "nextpnr: 8.4 / 62.5 ps": Line(tap_s=8.4e-12, tile_taps=2, tile_extra_s=54.1e-12,
                                        sigma_s=20e-12)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--hits", type=int, default=10 ** 6, help="test hits per line")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    started = time.monotonic()
    print("line                        | tap ps | DNL raw | INL raw | code error ps before/after "
          "| DNL/INL 50 ps after | RMS ps before | RMS ps after (12.5 / 50 ps LSB)")
    for name, line in LINES.items():
        fine = evaluate(line, test_hits=args.hits, lsb_select=2, seed=args.seed)
        coarse = evaluate(line, test_hits=args.hits, lsb_select=0, seed=args.seed)
        tap = fine["mean_tap_s"]
        after = np.abs(fine["code_inl_after_s"]).max()
        print(f"{name:<27} | {tap * 1e12:6.2f} | {np.abs(fine['dnl_before']).max():7.2f} | "
              f"{np.abs(fine['inl_before']).max():7.2f} | "
              f"{np.abs(fine['code_inl_before_s']).max() * 1e12:6.1f} / {after * 1e12:4.1f} "
              f"({after / tap:.2f} tap) | {np.abs(fine['dnl_after']).max():.2f} / "
              f"{np.abs(fine['inl_after']).max():.2f} | {fine['rms_before_s'] * 1e12:13.1f} | "
              f"{fine['rms_after_s'] * 1e12:.1f} / {coarse['rms_after_s'] * 1e12:.1f}")
    print()
    print("FLISS | readout        | ToF ns (truth) | ToF error ps | FWHM ns (truth) | peaks")
    for row in scene_comparison(seed=args.seed):
        print(f"{row['fliss']:<5} | {row['readout']:<14} | {row['tof_s'] * 1e9:6.3f} "
              f"({row['truth_tof_s'] * 1e9:.3f}) | {(row['tof_s'] - row['truth_tof_s']) * 1e12:12.0f} "
              f"| {row['fwhm_s'] * 1e9:6.3f} ({row['truth_fwhm_s'] * 1e9:.3f}) | {row['peaks']}")
    print(f"\n{time.monotonic() - started:.0f} s")


if __name__ == "__main__":
    main()
