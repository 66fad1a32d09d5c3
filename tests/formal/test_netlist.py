"""The boards' gate-level netlists under the top level's cocotb tests, through its pins only.

Each board's bitstream design is synthesized by the Yosys script of its build
(:mod:`fliss.boards.netlist`) and simulated with Yosys's cell models, with the expected values of
the RTL runs (tests/gateware/test_cocotb_top.py). The runs take minutes: they run with
``FLISS_NETLIST=1`` (``make test-netlist``), and need the ``boards`` extra.
"""

import json
import os
from pathlib import Path
from xml.etree import ElementTree

import pytest

from fliss.sim.benches.runner import run_cocotb, simulator_available


NETLIST = os.environ.get("FLISS_NETLIST") in ("1", "full")
#: ``FLISS_NETLIST=full`` runs every run of :data:`RUNS`; ``1`` (``.ci/run``) those that fit
#: CI's time.
FULL = os.environ.get("FLISS_NETLIST") == "full"
pytestmark = pytest.mark.skipif(
    not NETLIST, reason="gate-level runs take minutes: set FLISS_NETLIST=1 to run them")

BUILD = Path(__file__).resolve().parents[2] / "build" / "netlist"

#: Fuzz frames on a netlist: enough for a NAK of every kind of damage (the 10 000-frame fuzz
#: runs on the RTL).
FUZZ_FRAMES = 40

#: The runs of each board's netlist: (simulator, bench module, its tests or None for all, more
#: environment, whether only ``FLISS_NETLIST=full`` runs it). The default runs (CI's) cover on
#: each board: power-up (the first frames; on the iCEBreaker, outputs never X from
#: configuration on), the link (a register of every group written and read back, a refusal, a
#: NAK), the delay sequences of every mode the build has against the model, and a histogram of
#: injected events in compact readout (:mod:`fliss.sim.benches.netlist_top`); on the ULX3S, a
#: depth frame too. The ULX3S runs on Verilator (some 5 000 to 9 000 cycles/s on its netlist);
#: its power-up's X check needs Icarus (40 to 90 cycles/s on it, and some 3 minutes to compile),
#: so only ``full`` runs it: through the reset hold, and to the first PING.
#: A board's runs are one scope for pytest-xdist (``tests/conftest.py``): the two boards run
#: side by side.
#: The iCEBreaker's smaller netlist runs on Icarus (some 1 000 cycles/s); Verilator does not
#: take its pads (SB_IO), tristate on the top level's pins. ``full`` adds the RTL's longer
#: benches: every register with refusals, fuzz, raw events, closed-loop and pixel histograms.
RUNS = {
    "ulx3s": [
        ("icarus", "fliss.sim.benches.netlist_top", ["test_power_up"],
         {"FLISS_TB_SHORT": "levels", "FLISS_TB_UNLOCKED_CYCLES": "20"}, True),
        ("verilator", "fliss.sim.benches.netlist_top", None, {}, False),
        ("verilator", "fliss.sim.benches.top_depth", None, {}, False),
        ("icarus", "fliss.sim.benches.netlist_top", ["test_power_up"],
         {"FLISS_TB_SHORT": "1"}, True),
        ("verilator", "fliss.sim.benches.top", None, {}, True),
    ],
    "icebreaker": [
        ("icarus", "fliss.sim.benches.netlist_top", None,
         {"FLISS_TB_PULSES": "100", "FLISS_TB_UNLOCKED_CYCLES": "20"}, False),
        ("icarus", "fliss.sim.benches.top",
         ["test_identify_and_registers", "test_histogram_closed_loop", "test_pixel_histograms"],
         {}, True),
    ],
}


#: Routed netlists (nextpnr's placed and routed design read back; ``FLISS_NETLIST=full``
#: only), and how far their power-up test goes on Icarus (``FLISS_TB_SHORT``). The ULX3S's
#: routed design is read back but not simulated (:mod:`fliss.boards.routed`).
ROUTED = {"icebreaker": "1"}


def _netlist(board, routed=False):
    pytest.importorskip("amaranth_boards", reason="needs the boards extra: "
                                                  "pip install -e '.[boards]'")
    from fliss.boards.netlist import simulation_sources, synthesize
    from fliss.boards.routed import place_and_route, routed_simulation_sources
    netlist = synthesize(board)
    if routed:
        routed_netlist = place_and_route(netlist)
        sources, defines = routed_simulation_sources(routed_netlist)
    else:
        sources, defines = simulation_sources(netlist)
    return netlist, sources, defines


def _speed(results_xml, clock_hz):
    # Simulated cycles per second of wall time, over the run's tests.
    sim_ns = wall_s = 0.0
    for case in ElementTree.parse(results_xml).iter("testcase"):
        properties = {p.get("name"): p.get("value") for p in case.iter("property")}
        sim_ns += float(properties.get("sim_time_duration", 0))
        wall_s += float(case.get("time", 0))
    return sim_ns * 1e-9 * clock_hz / wall_s if wall_s else 0.0, wall_s


def run_netlist(board, simulator, test_module, testcase=None, env=None, *, routed=False):
    """Run ``test_module`` (the tests ``testcase``) on ``board``'s netlist (its routed netlist
    if ``routed``); returns the :class:`~fliss.sim.benches.runner.CocotbResults` and the speed
    in cycles per second."""
    if not simulator_available(simulator):
        pytest.fail(f"simulator {simulator} is not installed")
    from fliss.boards.netlist import WRAPPER
    from fliss.boards import PllClocking
    netlist, sources, defines = _netlist(board, routed)
    design = netlist.design
    # Cycles from the PLL's lock to the end of the design's reset: the board's hold, and the
    # two resynchronisers; then, for single-port banks, their clearing.
    init = PllClocking.hold_cycles + 8
    if design.histogram_ram == "single":
        init += 1 << design.bank_bits
    extra_env = {"FLISS_TB_CLOCK_HZ": repr(netlist.clock_hz), "FLISS_TB_BAUD": str(design.baud),
                 "FLISS_TB_MAXIMA": json.dumps(design.register_maxima()),
                 "FLISS_TB_BANK_BITS": str(design.bank_bits),
                 "FLISS_TB_INIT_CYCLES": str(init), "FLISS_TB_FUZZ_FRAMES": str(FUZZ_FRAMES),
                 "FLISS_TB_KEYED": str(int(design.keyed)),
                 "FLISS_TB_COMPACT": str(int(design.compact_readout)), **(env or {})}
    build_dir = BUILD / board / ("cocotb_routed" if routed else "cocotb")
    results = run_cocotb(simulator, verilog_path=sources[0], sources=sources[1:],
                         defines=defines, includes=[sources[-1].parent], toplevel=WRAPPER,
                         test_module=test_module, build_dir=build_dir, testcase=testcase,
                         extra_env=extra_env)
    speed, wall_s = _speed(build_dir / simulator / f"{WRAPPER}.results.xml", netlist.clock_hz)
    print(f"{board} {'routed ' if routed else ''}netlist, {simulator}, {test_module}: "
          f"{results.counts} in {wall_s:.0f} s, "
          f"{speed:.0f} cycles/s")
    return results, speed


@pytest.mark.parametrize("board, simulator, test_module, testcase, env, full_only", [
    (board, *run) for board, runs in RUNS.items() for run in runs],
    ids=lambda value: value.rsplit(".", 1)[-1] if isinstance(value, str) else None)
def test_netlist(board, simulator, test_module, testcase, env, full_only, cocotb_counts):
    if full_only and not FULL:
        pytest.skip("a longer run: FLISS_NETLIST=full (make test-netlist NETLIST=full)")
    results, _ = run_netlist(board, simulator, test_module, testcase, env)
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected


@pytest.mark.parametrize("board, short", ROUTED.items())
def test_routed_power_up(board, short, cocotb_counts):
    """The routed netlist from configuration on: outputs at their idle levels, never X, through
    the PLL's lock and the reset hold; then it answers PING."""
    if not FULL:
        pytest.skip("a longer run: FLISS_NETLIST=full (make test-netlist NETLIST=full)")
    results, _ = run_netlist(board, "icarus", "fliss.sim.benches.netlist_top", ["test_power_up"],
                             {"FLISS_TB_SHORT": short, "FLISS_TB_UNLOCKED_CYCLES": "20"},
                             routed=True)
    cocotb_counts("icarus", results)
    assert results.failed == []
    assert results.passed == results.expected
