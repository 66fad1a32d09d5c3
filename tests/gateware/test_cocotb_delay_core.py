"""cocotb testbenches of the delay core on Icarus and Verilator (generated Verilog)."""

from pathlib import Path

import pytest
from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from fliss.hdl.delay.core import DelayCore
from fliss.hdl.delay.source import Delay, DelaySource
from fliss.sim.benches.runner import run_cocotb, write_verilog

from conftest import bench_runs


BUILD = Path(__file__).resolve().parents[2] / "build" / "cocotb"
#: The delay core's short run on Icarus (`make test`; `make test-long` runs the whole bench
#: there, Verilator in both): one case of each kind from reset, the reconfigurations, the
#: resets in the middle of a run, and the keyed source over a few of its runs (its
#: pulses below: 100 000 in the whole bench).
DELAY_CORE_SHORT = ["test_mseq/length=5", "test_masked/mask_width=6", "test_grid/mode=MASKED",
                    "test_effective_prf/length=5", "test_reconfigure", "test_reset_and_restart",
                    "test_keyed"]
DELAY_CORE_SHORT_KEYED_PULSES = 5_000


@pytest.fixture(scope="module")
def delay_core_verilog():
    return write_verilog(DelayCore(), "delay_core", BUILD / "delay_core" / "delay_core.v")


@pytest.mark.parametrize("simulator, run", bench_runs(), indirect=["simulator"])
def test_delay_core(simulator, run, delay_core_verilog, cocotb_counts):
    short = run == "short"
    results = run_cocotb(
        simulator, verilog_path=delay_core_verilog, toplevel="delay_core",
        test_module="fliss.sim.benches.delay_core", build_dir=BUILD / "delay_core",
        testcase=DELAY_CORE_SHORT if short else None,
        extra_env={"FLISS_TB_KEYED_PULSES": str(DELAY_CORE_SHORT_KEYED_PULSES)} if short else {})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected


class _DelaySourcePorts(wiring.Component):
    """:class:`DelaySource` with ``delays.valid`` as a signal (always high): its stream is
    ``always_valid``, whose ``valid`` is a constant, and a Verilog port must be a signal."""

    def __init__(self):
        self.source = DelaySource()
        super().__init__({
            "settings": In(self.source.settings.shape()),
            "load":     In(1),
            "delays":   Out(stream.Signature(Delay)),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.source = source = self.source
        m.d.comb += [
            source.settings.eq(self.settings),
            source.load.eq(self.load),
            source.delays.ready.eq(self.delays.ready),
            self.delays.valid.eq(source.delays.valid),
            self.delays.payload.eq(source.delays.payload),
        ]
        return m


@pytest.fixture(scope="module")
def delay_source_verilog():
    return write_verilog(_DelaySourcePorts(), "delay_source",
                         BUILD / "delay_source" / "delay_source.v")


def test_delay_source(simulator, delay_source_verilog, cocotb_counts):
    results = run_cocotb(
        simulator, verilog_path=delay_source_verilog, toplevel="delay_source",
        test_module="fliss.sim.benches.delay_source", build_dir=BUILD / "delay_source",
        extra_env={"FLISS_TB_TRANSFERS": str(100_000 if simulator == "verilator" else 25_000)})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected
