"""cocotb tests of the whole top level through its pins, on Icarus and Verilator."""

import gc
import json
import warnings
from pathlib import Path

import pytest
from amaranth.hdl import UnusedElaboratable

from fliss.hdl.delay.source import DelayMode
from fliss.hdl.finetdc import HitInput
from fliss.hdl.registers import REGISTERS, AcquisitionMode, TdcSource
from fliss.hdl.delay.settings import BANK_BITS
from fliss.hdl.top import FlissTop, SMALL
from fliss.sim.benches.runner import run_cocotb, write_verilog

from conftest import bench_runs


BUILD = Path(__file__).resolve().parents[2] / "build" / "cocotb" / "fliss_top"
BUILD_SMALL = BUILD.with_name("fliss_top_small")
BAUD = 12_000_000
#: Fuzz frames through the UART pins per simulator. A frame and its reply take about 40 µs of
#: simulated time (3200 cycles), and the whole top level simulates at some 10^5 cycles/s in
#: Verilator and 10^4 in Icarus; the 10 000-frame fuzz runs on the link at one byte per cycle
#: (tests/gateware/test_cocotb_link.py).
FUZZ_FRAMES = {"icarus": 100, "verilator": 300}


#: Histogram banks of the top per simulator: Verilator runs the ULX3S's (64 blocks of 1024 words
#: a bank); Icarus, which spends its time on every RAM block's processes each cycle, banks of 8
#: blocks: the same read tree and pipeline, an eighth of the blocks (the test in about half the
#: time).
TOP_BANK_BITS = {"icarus": 13, "verilator": BANK_BITS}

#: The short runs on Icarus (`make test`; `make test-long` runs the whole bench there): the
#: closed loops from power-up, through the histogram's memories (the small build's single-port
#: banks, cleared after reset), the raw FIFO and the link. Verilator runs the whole bench in
#: `make test`: the registers written and read back, the fuzz.
TOP_SHORT = ["test_raw_events_closed_loop", "test_histogram_closed_loop"]
SMALL_SHORT = ["test_histogram_closed_loop", "test_pixel_histograms"]


@pytest.mark.parametrize("simulator, run", bench_runs(), indirect=["simulator"])
def test_top(simulator, run, cocotb_counts):
    bank_bits = TOP_BANK_BITS[simulator]
    top = FlissTop(baud=BAUD, bank_bits=bank_bits)
    maxima = top.register_maxima()      # (no fine TDC: tdc_source up to 1)
    verilog = write_verilog(top, "fliss_top", BUILD / simulator / "fliss_top.v")
    results = run_cocotb(
        simulator, verilog_path=verilog, toplevel="fliss_top",
        test_module="fliss.sim.benches.top", build_dir=BUILD,
        testcase=TOP_SHORT if run == "short" else None,
        extra_env={"FLISS_TB_BAUD": str(BAUD), "FLISS_TB_BANK_BITS": str(bank_bits),
                   "FLISS_TB_MAXIMA": json.dumps(maxima),
                   "FLISS_TB_FUZZ_FRAMES": str(FUZZ_FRAMES[simulator])})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected


@pytest.mark.parametrize("simulator, run", bench_runs(), indirect=["simulator"])
def test_top_small(simulator, run, cocotb_counts):
    # The iCE40UP5K build through its pins: every register written (in range, at its maximum,
    # above it) and read back against the model with this build's maxima and bank, a
    # histogram, and per-pixel histograms (Icarus's short run: SMALL_SHORT).
    top = FlissTop(baud=BAUD, **SMALL)
    maxima = top.register_maxima()
    verilog_path = write_verilog(top, "fliss_top", BUILD_SMALL / "fliss_top.v")
    results = run_cocotb(
        simulator, verilog_path=verilog_path, toplevel="fliss_top",
        test_module="fliss.sim.benches.top", build_dir=BUILD_SMALL,
        testcase=SMALL_SHORT if run == "short" else [
            "test_identify_and_registers", "test_histogram_closed_loop", "test_pixel_histograms"],
        extra_env={"FLISS_TB_BAUD": str(BAUD), "FLISS_TB_MAXIMA": json.dumps(maxima),
                   "FLISS_TB_BANK_BITS": str(top.bank_bits),
                   "FLISS_TB_INIT_CYCLES": str(1 << top.bank_bits)})   # (clearing the SPRAMs)
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected


@pytest.mark.parametrize("kwargs, exception, message", [
    (dict(histogram_ram="flash"), ValueError,
     "Histogram RAM must be one of 'dual', 'single', not 'flash'"),
    (dict(aggressor_delays=0), TypeError, "aggressor_delays must be True or False, not 0"),
    (dict(aggressor=None), TypeError, "aggressor must be True or False, not None"),
    (dict(raw_events="no"), TypeError, "raw_events must be True or False, not 'no'"),
    (dict(raw_events=False), ValueError,
     "A build with the depth engine must have raw events too: depth=True needs raw_events=True"),
    (dict(period_width=16), ValueError,
     "Period width must be an integer from 17 to 32 bits, not 16"),
])
def test_top_refuses(construction_error, kwargs, exception, message):
    assert construction_error(lambda: FlissTop(**kwargs), exception) == message


def _built(module, name):
    try:
        module.submodules[name]
    except AttributeError:
        return False
    return True


@pytest.mark.parametrize("options", [{}, dict(aggressor_delays=False), SMALL,
                                     dict(fine_tdc=True), dict(fine_tdc=True, aggressor=False)],
                         ids=["full", "no-aggressor-delays", "small", "fine-tdc",
                              "fine-tdc-no-aggressor"])
def test_top_register_file_takes_what_the_top_runs(options):
    # The register file accepts every value the blocks the top level builds can take, and only
    # those: aggressor delay modes its aggressor can run (none without an aggressor), periods
    # and pulse widths that fit its delay core's settings, raw events only if it has the FIFO,
    # depth mode and settings only with the depth engine. The other registers keep the register
    # map's maxima.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnusedElaboratable)    # elaborated, never converted
        flisstop = FlissTop(**options)
        top = flisstop.elaborate(None)
        maxima = top.submodules.link.maxima
        core = top.submodules.core
        lowered = {}
        for name in ("period", "aggressor_period"):
            lowered[name] = (1 << core.period_width) - 1
        for name in ("pulse_width", "aggressor_width"):
            lowered[name] = (1 << core.pulse_width_width) - 1
        lowered["acquisition"] = max(mode.value for mode in AcquisitionMode
                                     if _built(top, "raw_fifo") or
                                     mode == AcquisitionMode.HISTOGRAM)
        if _built(top, "aggressor"):
            aggressor = top.submodules.aggressor
            lowered["aggressor_delay_mode"] = max(
                mode.value for mode in DelayMode if aggressor.delay_source or mode == DelayMode.OFF)
        else:
            # no aggressor: its registers hold values as wide as their reset values only
            lowered["aggressor"] = 0
            for register in REGISTERS:
                if register.name.startswith("aggressor_"):
                    reset = register.reset_value(flisstop.clock_hz)
                    assert maxima[register.name] < 2 * max(reset, register.minimum, 1)
                    lowered[register.name] = maxima[register.name]
        if not _built(top, "depth"):
            # no depth engine: its settings hold values as wide as their reset values only
            for register in REGISTERS:
                if register.group == "depth":
                    reset = register.reset_value(flisstop.clock_hz)
                    assert reset <= maxima[register.name] < 2 * max(reset, register.minimum, 1)
                    lowered[register.name] = maxima[register.name]
        lowered["pixel_bits"] = top.submodules.histogram.max_pixel_bits
        if not _built(top, "fine"):
            # no fine TDC: the coarse TDC at most, and its registers 0
            lowered["tdc_source"] = TdcSource.COARSE.value
            for register in REGISTERS:
                if register.group == "fine_tdc":
                    lowered[register.name] = 0
        elif "aggressor_laser_pad" not in flisstop.signature.members:
            # the fine TDC's internal loopback reads the laser's pad only
            assert "laser_pad" in flisstop.signature.members
            lowered["tdc_input"] = HitInput.LASER.value
        if not core.keyed:
            # no keyed source: delay modes up to masked, and no key or IV but 0
            lowered["delay_mode"] = DelayMode.MASKED.value
            for register in REGISTERS:
                if register.group == "keying":
                    lowered[register.name] = 0
        assert maxima == {r.name: min(r.maximum, lowered.get(r.name, r.maximum))
                          for r in REGISTERS}
        del flisstop, top, core
        gc.collect()
