"""Depth bias of a single-hit TDC's histogram against the echo's detections per pulse, with and
without the pile-up correction (:mod:`fliss.analysis.pileup`), side by side.

The scene simulator (:mod:`fliss.sim.scene`) makes the histograms: one pixel, a target 4 m
away, the paper's 2.1 ns laser pulse and 100 ps jitter, 100 kHz of ambient light, FLISS off at
1 MHz, the echo from 0.01 to 5 detections per pulse. The depth is that of the tallest peak
(what ``fliss analyze`` prints as the ToF) of each histogram as it is
(:func:`fliss.analysis.peaks.find_peaks`) and corrected over its laser cycles
(:func:`fliss.analysis.pileup.corrected_peaks`, ``fliss analyze --pileup``); its bias
is the mean over ``--acquisitions`` histograms, minus 4 m, ± the standard error of that mean.

Cases (the TDC keeps the first or the last detected photon of a cycle; the SPAD's dead time):

* ``first, 20 ns``: Coates' correction (``--pileup first``);
* ``last, 0 ns``: its counterpart (``--pileup last --dead-time 0ns``), every photon of the
  cycle detected;
* ``last, 20 ns`` (the paper's sensor, the virtual boards): the dead time, longer than the
  pulse, lets the SPAD detect only the first photon of the echo, so the echo piles up as for a
  first-photon TDC: the counterpart with the dead time (``--pileup last --dead-time 20ns``),
  and, to show what a wrong law does, without it and Coates'.

Usage: ``python benchmarks/pileup_depth_bias.py [--acquisitions N] [--t-int S]``
"""

import argparse

import numpy as np

from fliss.analysis.peaks import find_peaks
from fliss.analysis.pileup import corrected_peaks
from fliss.hdl.event import TDC_LSB_S
from fliss.sim.scene import SPEED_OF_LIGHT, Detector, Scene, acquire


DISTANCE_M = 4.0
FLUXES = (0.01, 0.03, 0.1, 0.3, 0.5, 1.0, 2.0, 3.0, 5.0)
#: (the photon kept, the dead time, the corrections: (label, keep, dead time given))
CASES = (("first", 20e-9, (("first", "first", 0.0),)),
         ("last", 0.0, (("last", "last", 0.0),)),
         ("last", 20e-9, (("last 20ns", "last", 20e-9), ("last 0ns", "last", 0.0),
                          ("first", "first", 0.0))))


def depth_m(histogram, cycles=None, keep=None, dead_s=0.0):
    """Depth of the tallest peak, or NaN without one; with ``keep``, corrected for pile-up
    over ``cycles`` as ``fliss analyze --pileup KEEP --dead-time DEAD`` does."""
    peaks = find_peaks(histogram, bin_s=TDC_LSB_S) if keep is None else \
        corrected_peaks(histogram, cycles, keep, bin_s=TDC_LSB_S,
                        dead_bins=int(round(dead_s / TDC_LSB_S)))[1]
    if not peaks:
        return float("nan")
    return max(peaks, key=lambda peak: peak.height).position_s * SPEED_OF_LIGHT / 2


def bias_mm(values):
    values = np.asarray(values) - DISTANCE_M
    mean = 1e3 * float(np.nanmean(values))
    error = 1e3 * float(np.nanstd(values, ddof=1) / np.sqrt(np.sum(np.isfinite(values))))
    return f"{mean:+8.1f} ± {error:4.1f}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--acquisitions", type=int, default=8)
    parser.add_argument("--t-int", type=float, default=0.02, help="seconds per histogram")
    args = parser.parse_args()
    print(f"depth bias (mm) of the tallest peak, mean of {args.acquisitions} histograms of "
          f"{args.t_int * 1e3:g} ms at 1 MHz ± its standard error; target {DISTANCE_M} m")
    for keep, dead_s, corrections in CASES:
        header = f"{'detections/pulse':>16}  {'raw':>15}" + "".join(
            f"  {'corrected ' + label:>19}" for label, _, _ in corrections)
        print(f"\nTDC keeps the {keep} photon, dead time {dead_s * 1e9:g} ns\n{header}")
        for flux in FLUXES:
            scene = Scene(distance_m=DISTANCE_M, detections_per_pulse=flux, keep=keep,
                          background_hz=1e5, detector=Detector(dead_time_s=dead_s))
            run = acquire(scene, args.t_int, args.acquisitions, seed=1)
            raw = [depth_m(histogram) for histogram in run.histograms]
            row = f"{flux:>16g}  {bias_mm(raw):>15}"
            for _, name, given_s in corrections:
                fixed = [depth_m(histogram, int(cycles), name, given_s)
                         for histogram, cycles in zip(run.histograms, run.cycles)]
                row += f"  {bias_mm(fixed):>19}"
            print(row, flush=True)


if __name__ == "__main__":
    main()
