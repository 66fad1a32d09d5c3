"""cocotb tests of the whole top level through its pins, on Icarus and Verilator."""

import gc
import warnings
from pathlib import Path

import pytest
from amaranth.hdl import UnusedElaboratable

from fliss.hdl.top import FlissTop
from fliss.sim.cocotb_runner import run_cocotb, write_verilog


BUILD = Path(__file__).resolve().parent.parent / "build" / "cocotb" / "fliss_top"
BAUD = 12_000_000
#: Fuzz frames through the UART pins per simulator. A frame and its reply take about 40 µs of
#: simulated time (3200 cycles), and the whole top level simulates at some 10^5 cycles/s in
#: Verilator and 10^4 in Icarus; the 10 000-frame fuzz runs on the link at one byte per cycle
#: (tests/test_cocotb_link.py).
FUZZ_FRAMES = {"icarus": 100, "verilator": 300}


@pytest.fixture(scope="module")
def top_verilog():
    return write_verilog(FlissTop(baud=BAUD), "fliss_top", BUILD / "fliss_top.v")


def test_top(simulator, top_verilog, cocotb_counts):
    passed, failed, skipped = run_cocotb(
        simulator, verilog_path=top_verilog, toplevel="fliss_top",
        test_module="fliss.sim.tb_top", build_dir=BUILD,
        extra_env={"FLISS_TB_BAUD": str(BAUD),
                   "FLISS_TB_FUZZ_FRAMES": str(FUZZ_FRAMES[simulator])})
    cocotb_counts(simulator, passed, failed, skipped)
    assert failed == 0
    assert passed == 4


@pytest.mark.parametrize("kwargs, exception, message", [
    (dict(histogram_ram="flash"), ValueError,
     "Histogram RAM must be one of 'dual', 'single', not 'flash'"),
    (dict(aggressor_delays=0), TypeError, "aggressor_delays must be True or False, not 0"),
])
def test_top_refuses(construction_error, kwargs, exception, message):
    assert construction_error(lambda: FlissTop(**kwargs), exception) == message


def test_top_without_aggressor_delays_refuses_their_modes():
    # The build's register file lowers the maximum of the mode it cannot run, and only that.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnusedElaboratable)    # built, never elaborated
        assert FlissTop(aggressor_delays=False).register_maxima() == \
            {"aggressor_delay_mode": 0}
        assert FlissTop().register_maxima() == {}
        gc.collect()
