"""cocotb tests of the whole top level through its pins, on Icarus and Verilator."""

import gc
import warnings
from pathlib import Path

import pytest
from amaranth.hdl import UnusedElaboratable

from fliss.hdl.delay import DelayMode
from fliss.hdl.registers import REGISTERS
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


@pytest.mark.parametrize("aggressor_delays", [True, False])
def test_top_register_file_takes_what_the_aggressor_runs(aggressor_delays):
    # The register file accepts every aggressor delay mode the built aggressor can run, and
    # only those; the other registers keep the register map's maxima.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnusedElaboratable)    # elaborated, never converted
        top = FlissTop(aggressor_delays=aggressor_delays).elaborate(None)
        command, aggressor = top.submodules.command, top.submodules.aggressor
        runnable = [mode.value for mode in DelayMode
                    if aggressor.delay_source or mode == DelayMode.OFF]
        assert max(runnable) == command.maxima["aggressor_delay_mode"]
        assert {name: maximum for name, maximum in command.maxima.items()
                if name != "aggressor_delay_mode"} == \
            {r.name: r.maximum for r in REGISTERS if r.name != "aggressor_delay_mode"}
        del top, command, aggressor
        gc.collect()
