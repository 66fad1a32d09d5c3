"""The top level in depth mode through its pins, against the depth model, on Icarus and
Verilator."""

from pathlib import Path

from fliss.hdl.top import FlissTop
from fliss.sim.benches.runner import run_cocotb, write_verilog


BUILD = Path(__file__).resolve().parents[2] / "build" / "cocotb" / "fliss_top_depth"
BAUD = 12_000_000


def test_top_depth(simulator, cocotb_counts):
    verilog = write_verilog(FlissTop(baud=BAUD), "fliss_top", BUILD / "fliss_top.v")
    results = run_cocotb(
        simulator, verilog_path=verilog, toplevel="fliss_top",
        test_module="fliss.sim.benches.top_depth", build_dir=BUILD,
        extra_env={"FLISS_TB_BAUD": str(BAUD)})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected
