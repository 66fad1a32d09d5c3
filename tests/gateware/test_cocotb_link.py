"""Random and mutated frames through the link, on Icarus and Verilator."""

from pathlib import Path

import pytest

from fliss.sim.benches.runner import run_cocotb, write_verilog
from fliss.sim.benches.link_top import LinkTop


BUILD = Path(__file__).resolve().parents[2] / "build" / "cocotb" / "link_top"
#: Frames per simulator and run: `make test` runs the short fuzz (the same frames' first
#: thousand, every check), `make test-long` (marker ``long``, run by CI) the full 10 000 frames.
FRAMES = {"short": 1_000, "long": 10_000}


@pytest.mark.parametrize("length", ["short", pytest.param("long", marks=pytest.mark.long)])
def test_link_fuzz(simulator, length, cocotb_counts):
    verilog = write_verilog(LinkTop(), "link_top", BUILD / "link_top.v")
    results = run_cocotb(
        simulator, verilog_path=verilog, toplevel="link_top", test_module="fliss.sim.benches.link",
        build_dir=BUILD, extra_env={"FLISS_TB_FUZZ_FRAMES": str(FRAMES[length])})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected
