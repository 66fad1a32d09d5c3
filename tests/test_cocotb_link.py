"""Random and mutated frames through the link, on Icarus and Verilator."""

from pathlib import Path

from fliss.sim.benches.runner import run_cocotb, write_verilog
from fliss.sim.benches.link_top import LinkTop


BUILD = Path(__file__).resolve().parent.parent / "build" / "cocotb" / "link_top"
#: Frames per simulator: Icarus calls into Python far more slowly than Verilator.
FRAMES = {"icarus": 10_000, "verilator": 10_000}


def test_link_fuzz(simulator, cocotb_counts):
    verilog = write_verilog(LinkTop(), "link_top", BUILD / "link_top.v")
    results = run_cocotb(
        simulator, verilog_path=verilog, toplevel="link_top", test_module="fliss.sim.benches.link",
        build_dir=BUILD, extra_env={"FLISS_TB_FUZZ_FRAMES": str(FRAMES[simulator])})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected
