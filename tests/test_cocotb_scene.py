"""cocotb test of the virtual board's sensor model on the top level: the line scene's events
arrive with their pixel addresses and collision flags, on Icarus and Verilator."""

from pathlib import Path

import pytest

from fliss.hdl.top import FlissTop
from fliss.sim.benches.runner import run_cocotb, write_verilog


BUILD = Path(__file__).resolve().parent.parent / "build" / "cocotb" / "fliss_top_scene"
BAUD = 12_000_000


@pytest.fixture(scope="module")
def top_verilog():
    return write_verilog(FlissTop(baud=BAUD), "fliss_top", BUILD / "fliss_top.v")


@pytest.mark.parametrize("case", ["column", "per_pixel", "burst"])
def test_line_scene_on_the_sensor_bus(simulator, top_verilog, cocotb_counts, case):
    results = run_cocotb(
        simulator, verilog_path=top_verilog, toplevel="fliss_top",
        test_module="fliss.sim.benches.scene", build_dir=BUILD,
        extra_env={"FLISS_TB_BAUD": str(BAUD), "FLISS_TB_CASE": case})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected
