"""The depth engine against its model, bit for bit, on Icarus and Verilator."""

from pathlib import Path

from fliss.hdl.depth.engine import DepthEngine
from fliss.sim.benches.runner import run_cocotb, write_verilog


BUILD = Path(__file__).resolve().parents[2] / "build" / "cocotb" / "depth_engine"
#: Frames per simulator: Icarus calls into Python far more slowly than Verilator.
FRAMES = {"icarus": 30, "verilator": 60}


def test_depth_engine(simulator, cocotb_counts):
    verilog = write_verilog(DepthEngine(), "depth_engine", BUILD / "depth_engine.v")
    results = run_cocotb(
        simulator, verilog_path=verilog, toplevel="depth_engine", test_module="fliss.sim.benches.depth",
        build_dir=BUILD, extra_env={"FLISS_TB_DEPTH_FRAMES": str(FRAMES[simulator])})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected
