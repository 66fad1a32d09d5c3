"""cocotb test of the virtual board's sensor model on the top level: the line scene's events
arrive with their pixel addresses and collision flags, on Icarus and Verilator; the fast
virtual board gives the same events as the cocotb run for the same seed."""

import json
from pathlib import Path

import pytest

from fliss.hdl.top import FlissTop
from fliss.sim.benches.runner import run_cocotb, write_verilog

from conftest import require_fast_harness


BUILD = Path(__file__).resolve().parents[2] / "build" / "cocotb" / "fliss_top_scene"
BAUD = 12_000_000


@pytest.fixture(scope="module")
def top_verilog():
    return write_verilog(FlissTop(baud=BAUD), "fliss_top", BUILD / "fliss_top.v")


#: Each case on each simulator: Verilator runs all three in `make test` (and compares the
#: column sensor's case with the fast board); Icarus, at a tenth of its speed, in `make
#: test-long` (the top level's power-up and closed loops on Icarus are `test_cocotb_top`'s).
RUNS = [pytest.param(simulator, case, id=f"{simulator}-{case}",
                     marks=[pytest.mark.long] if simulator == "icarus" else [])
        for simulator in ("icarus", "verilator") for case in ("column", "per_pixel", "burst")]


@pytest.mark.parametrize("simulator, case", RUNS, indirect=["simulator"])
def test_line_scene_on_the_sensor_bus(simulator, top_verilog, cocotb_counts, case, tmp_path):
    record = tmp_path / "cocotb.json"
    results = run_cocotb(
        simulator, verilog_path=top_verilog, toplevel="fliss_top",
        test_module="fliss.sim.benches.scene", build_dir=BUILD,
        extra_env={"FLISS_TB_BAUD": str(BAUD), "FLISS_TB_CASE": case,
                   "FLISS_TB_RECORD": str(record)})
    cocotb_counts(simulator, results)
    assert results.failed == []
    assert results.passed == results.expected
    if case == "column":
        _the_fast_board_gives_the_same_events(json.loads(record.read_text()))


def _the_fast_board_gives_the_same_events(reference):
    """The cocotb run of the ``column`` case (``reference``: what it recorded) against the fast
    virtual board (Verilator in the C++ harness, :mod:`fliss.sim.boards.fast`) with the same
    scene, seed and register writes: the gateware's TDC starts and aggressor edges are the same
    (but for where in time the commands arrived over the UART), so the scene gives the same
    events, window by window."""
    from fliss import protocol
    from fliss.hdl.protocol import PacketType, registers_layout
    from fliss.hdl.registers import BY_NAME
    from fliss.sim.benches.scene import CASES, SEED, case_registers, case_scene
    from fliss.sim.boards import harness
    from fliss.sim.boards.fast import FastBoard

    require_fast_harness()
    from fliss.host.virtual import board_folder, build_root
    library = harness.build(board_folder(build_root(), "fast", "verilator", baud=BAUD),
                            baud=BAUD)
    board = FastBoard(library, case_scene("column"), baud=BAUD, seed=SEED, record=True)
    board.start()
    encoder = protocol.PacketEncoder()
    for name, value in case_registers("column"):
        board.harness.write(encoder.frame(PacketType.WRITE, protocol.pack(
            registers_layout(1), address=BY_NAME[name].address, values=[value])))
    board.harness.write(encoder.frame(PacketType.START))
    board.run(CASES["column"][-1] * 80 + 20_000)

    # The same edges from the first start on, shifted by where the commands arrived
    edges = [tuple(edge) for edge in reference["edges"]]
    fast = board.sensor.edges
    first = [next(cycle for cycle, kind in run if kind == 0) for run in (edges, fast)]
    shifted = [(cycle - first[0], kind) for cycle, kind in edges if cycle >= first[0]]
    ours = [(cycle - first[1], kind) for cycle, kind in fast if cycle >= first[1]]
    common = min(len(shifted), len(ours))
    assert common > 100 and shifted[:common] == ours[:common]
    # The same events, window by window, over the windows both read out
    windows = min(len(reference["fed_windows"]), len(board.sensor.fed_windows)) - 1
    events = sum(reference["fed_windows"][:windows])
    assert windows > 50 and reference["fed_windows"][:windows] == \
        board.sensor.fed_windows[:windows]
    assert [tuple(event) for event in reference["fed"][:events]] == board.sensor.fed[:events]
