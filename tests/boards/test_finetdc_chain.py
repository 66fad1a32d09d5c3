"""benchmarks/finetdc_chain.py on a small routed design made up here: two lines of three carry
cells (one of them broken between two tiles, one flip-flop a tile away), and a one-line build's
cell names; the lines' taps and their merged codes against values worked out by hand."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest


_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "finetdc_chain.py"
_SPEC = importlib.util.spec_from_file_location("finetdc_chain", _PATH)
chain = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(chain)

#: Each line's taps' arrivals at their flip-flops, ns from the pin: line 0 from 1.000 ns, line 1
#: 35 ps later; 10 ps within a cell, 60 ps to the next
ARRIVALS_NS = {0: [1.000, 1.010, 1.070, 1.080, 1.140],
               1: [1.035, 1.045, 1.105, 1.115, 1.175]}
#: Each line's cells' sites: line 1 skips tile X22 before its last cell
SITES = {0: ["X10/Y5/SLICEA", "X10/Y5/SLICEB", "X10/Y5/SLICEC"],
         1: ["X21/Y7/SLICEC", "X21/Y7/SLICED", "X23/Y7/SLICEA"]}


def _design(lines=(0, 1), prefix="line{line}_"):
    # A routed netlist's cells and a report's per-net timing for the lines above: cell c's half
    # h drives tap 2c - 1 + h (cell 0's first half injects the hit and drives none)
    cells, nets, bit = {}, [], 100
    for line in lines:
        sites = SITES[line]
        for index, bel in enumerate(sites):
            for half in (0, 1):
                name = f"design.fine.line.{prefix.format(line=line)}{index}$CCU2_COMB{half}"
                bit += 1
                cells[name] = {"type": "TRELLIS_COMB", "attributes": {"NEXTPNR_BEL": bel},
                               "connections": {"F": [bit]}, "port_directions": {"F": "output"}}
                tap = 2 * index - 1 + half
                if tap < 0:
                    continue
                flip_flop = f"design.fine.line.sampled_{line}_{tap}"
                x, y = (10, 5) if line == 0 else (21, 7)
                if (line, tap) == (1, 4):
                    x = 24      # one tile from its cell's
                elif line == 1 and tap >= 3:
                    x = 23
                cells[flip_flop] = {"type": "TRELLIS_FF",
                                    "attributes": {"NEXTPNR_BEL": f"X{x}/Y{y}/SLICEA/FF0"},
                                    "connections": {"DI": [bit]}, "port_directions": {}}
                nets.append({"driver": name, "port": "F", "endpoints": [
                    {"cell": flip_flop, "delay": [ARRIVALS_NS[line][tap] - 0.1,
                                                  ARRIVALS_NS[line][tap]]},
                    {"cell": "design.other", "delay": [0.1, 0.2]}]})
    return cells, {"detailed_net_timings": nets, "critical_paths": []}


def test_each_lines_placement():
    cells, _ = _design()
    found = chain.chain_cells(cells)
    assert sorted(found) == [0, 1] and all(sorted(found[k]) == [0, 1, 2] for k in found)
    sites, breaks = chain.chain_sites(found[0])
    assert sites == {0: (10, 5, 0), 1: (10, 5, 1), 2: (10, 5, 2)} and breaks == []
    sites, breaks = chain.chain_sites(found[1])
    assert breaks == [(1, (21, 7, 3), (23, 7, 0))]
    distances = chain.flip_flop_distances(cells, chain.placement(cells))
    assert distances[0].tolist() == [0] * 5 and sorted(distances[1].tolist()) == [0] * 4 + [1]


def test_taps_and_merged_codes():
    _, report = _design()
    arrivals = chain.tap_arrivals(report)
    assert {line: [round(found[tap] * 1e9, 6) for tap in sorted(found)]
            for line, found in arrivals.items()} == ARRIVALS_NS
    # One period of 100 ps from the first tap: taps at 0, 10, 35, 45, 70, 80 ps, codes of 10,
    # 25, 10, 25, 10 and 20 ps (to the period's end)
    merged = chain.merged_codes(arrivals, 100e-12)
    assert merged["codes"] == 6
    assert merged["mean_code_s"] == pytest.approx(100e-12 / 6)
    assert merged["weighted_code_s"] == pytest.approx((3 * 100 + 2 * 625 + 400) / 100 * 1e-12)
    assert merged["widest_s"] == pytest.approx(25e-12)
    assert merged["starts_s"][1] == pytest.approx(35e-12) and merged["starts_s"][0] == 0
    # A period longer than the lines: the codes between the first and the last tap only
    merged = chain.merged_codes(arrivals, 1e-9)
    widths = np.diff(np.sort(np.concatenate(list(ARRIVALS_NS.values()))))
    assert merged["codes"] == 9 and merged["covered_s"] == pytest.approx(175e-12)
    assert merged["widest_s"] == pytest.approx(widths.max() * 1e-9)


def test_one_line_build_and_the_script(tmp_path, capsys):
    # A one-line build names its cells line_<cell>: line 0; taps at 0, 10, 70, 80 ps in a
    # period of 100 ps, codes of 10, 60, 10 and 20 ps
    cells, report = _design(lines=(0,), prefix="line_")
    assert list(chain.chain_cells(cells)) == [0] and len(chain.chain_cells(cells)[0]) == 3
    arrivals = chain.tap_arrivals(report)
    assert [round(arrivals[0][tap] * 1e9, 6) for tap in range(5)] == ARRIVALS_NS[0]
    merged = chain.merged_codes(arrivals, 100e-12)
    assert merged["codes"] == 4 and merged["mean_code_s"] == pytest.approx(25e-12)
    assert merged["weighted_code_s"] == pytest.approx(42e-12)
    # The script on a build folder of the two lines, with both files
    cells, report = _design()
    (tmp_path / "fliss_ulx3s.report.json").write_text(json.dumps(report))
    (tmp_path / "fliss_ulx3s.routed.json").write_text(json.dumps(
        {"modules": {"top": {"cells": cells}}}))
    chain.main([str(tmp_path), "--clock", "10e9"])
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == ("merged, 2 line(s): 6 codes in 0.10 ns from the first tap; mean code "
                       "16.7 ps, the code a hit falls in 19.5 ps on average, widest 25.0 ps; "
                       "first taps: line 0 +0.0 ps, line 1 +35.0 ps")
    assert "line 1: carry cells 3, from (21, 7, 2) to (23, 7, 0) (x, y, slice); steps to the " \
           "next slice: 1 of 2, breaks: 1" in out
