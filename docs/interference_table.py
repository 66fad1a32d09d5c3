"""The table of docs/interference.md: the largest number of equal-power aggressors for which
P(wrong depth) per 10 ms frame stays below 1e-3, for each scheme, with :func:`evaluate`.

For each scheme and aggressor kind the number of aggressors doubles (1, 2, 4, ...) until a point
fails (``p_wrong_depth >= 1e-3``), then bisects between the last pass and the first fail. A
point passes with no wrong frame out of ``--frames`` (1000: at most one frame in a thousand,
upper 95 % bound 3.8e-3; give more frames for a tighter bound).

Usage: ``python docs/interference_table.py [--frames N] [--max N] [--only NAME]``
"""

import argparse
import time

import numpy as np

from fliss.sim.interference import evaluate


SCHEMES = {
    "off": {"scheme": "off"},
    "mseq L=6": {"scheme": "mseq", "length": 6},
    "masked Wm=6": {"scheme": "masked", "mask_width": 6},
    "grid (mseq L=6)": {"scheme": "mseq", "length": 6, "grid": True},
    "mseq L=6, 1/2 cycle": {"scheme": "mseq", "length": 6, "fine_step": 2},
    "mseq L=6, 1/4 cycle": {"scheme": "mseq", "length": 6, "fine_step": 4},
    "mseq L=6, 1/8 cycle": {"scheme": "mseq", "length": 6, "fine_step": 8},
    "mseq L=6, 1/16 cycle": {"scheme": "mseq", "length": 6, "fine_step": 16},
}

KINDS = {"own oscillators (±50 ppm)": "fliss", "locked worst case": "locked"}

LIMIT = 1e-3


def passes(point, frames, seed, log):
    start = time.perf_counter()
    result = evaluate(dict(point, frames=frames, frames_per_run=20),
                      np.random.SeedSequence([seed, point["aggressors"]]))
    log(f"    N = {point['aggressors']:3d}: P(wrong) = {result['p_wrong_depth']:.4f} "
        f"[{result['p_wrong_depth_lo']:.4f}, {result['p_wrong_depth_hi']:.4f}], "
        f"P(ghost) = {result['p_ghost']:.3f}, S = {result['s_db'] or float('nan'):.1f} dB, "
        f"kept {result['signal_recorded']:.2f} ({time.perf_counter() - start:.0f} s)")
    return result["p_wrong_depth"] < LIMIT


def largest(base, frames, most, seed, log):
    """Largest N in 0 … most passing (most if all pass)."""
    good, bad, n = 0, None, 1
    while n <= most:
        if passes(dict(base, aggressors=n), frames, seed, log):
            good, n = n, 2 * n
        else:
            bad = n
            break
    if bad is None:
        return good, True
    while bad - good > 1:
        middle = (good + bad) // 2
        if passes(dict(base, aggressors=middle), frames, seed, log):
            good = middle
        else:
            bad = middle
    return good, False


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1000, help="frames per point")
    parser.add_argument("--max", type=int, default=64, help="most aggressors tried")
    parser.add_argument("--only", help="run only the schemes whose name contains this")
    parser.add_argument("--seed", type=int, default=2026)
    args = parser.parse_args()
    rows = []
    for name, scheme in SCHEMES.items():
        if args.only and args.only not in name:
            continue
        row = [name]
        for kind_name, kind in KINDS.items():
            print(f"{name}, {kind_name}:", flush=True)
            number, capped = largest(dict(scheme, aggressor_kind=kind), args.frames, args.max,
                                     args.seed, lambda line: print(line, flush=True))
            row.append(f"≥ {number}" if capped else str(number))
        rows.append(row)
    print()
    print("| scheme | " + " | ".join(KINDS) + " |")
    print("| --- | " + " | ".join("---" for _ in KINDS) + " |")
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
