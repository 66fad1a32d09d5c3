"""The fast virtual board (:mod:`fliss.sim.boards.fast`): the top level Verilated in the C++
harness, the sensor model in closed loop, against the cocotb board's sensor model.

The cocotb board tells its :class:`~fliss.sim.boards.sensor.SensorModel` each TDC start and
aggressor edge when its trigger fires and each window end one cycle after the window's range;
in one cycle, starts first, then aggressor edges, then window ends. Here the fast board runs the
gateware in raw mode, and a second sensor model with the same scene and seed is told the same
edges in that order, as the cocotb coroutines would tell it: both must give the same events,
window by window. Every event the fast board put on the bus must come back from the gateware in
the EVENTS packets, bit for bit, with the laser cycle it belongs to.
"""

import numpy as np
import pytest

from fliss import protocol
from fliss.hdl.protocol import PacketType, registers_layout
from fliss.hdl.registers import BY_NAME, AcquisitionMode
from fliss.protocol.events import EVENT_DTYPE
from fliss.sim import scene
from fliss.sim.boards import harness
from fliss.sim.boards.fast import AGGRESSOR, START, FastBoard
from fliss.sim.boards.sensor import SensorModel, StandInPins
from fliss.host.cli import main
from fliss.host.virtual import VIRTUAL_BAUD, board_folder, build_root

from conftest import require_fast_harness


@pytest.fixture(autouse=True)
def fast_harness():
    require_fast_harness()

#: Scenes: one pixel with an aggressor, the line with one TDC per pixel (several events a
#: window); laser period (cycles): 80 (1 MHz), 34 (the next start comes in the cycle the
#: window would close: it cuts the window short).
CASES = {"single": (None, 80), "single-cut": (None, 34), "line": ("per_pixel", 240)}


def _scene(sensor):
    pixels = None if sensor is None else scene.line_pixels(sensor=sensor)
    return scene.Scene(distance_m=4.0, detections_per_pulse=0.3 if sensor is None else 0.05,
                       background_hz=1e6, pixels=pixels,
                       aggressors=(scene.Aggressor(period_cycles=80, offset_s=0.0,
                                                   detections_per_pulse=0.2),))


def _write(encoder, name, value):
    return encoder.frame(PacketType.WRITE, protocol.pack(
        registers_layout(1), address=BY_NAME[name].address, values=[value]))


def _replayed(board_scene, edges, seed):
    """A sensor model told ``edges`` as the cocotb board tells them; its windows."""
    sensor = SensorModel(StandInPins(), board_scene, seed=seed, record=True)
    happenings = []
    for cycle, kind in edges:
        if kind == START:
            happenings.append((cycle, 0, sensor.on_start, cycle))
            happenings.append((cycle + sensor.window_cycles + 1, 2, sensor.on_window_end, cycle))
        else:
            assert kind == AGGRESSOR
            happenings.append((cycle, 1, sensor.on_aggressor, cycle))
    for _, _, handler, cycle in sorted(happenings, key=lambda item: item[:2]):
        handler(cycle)
    return sensor


@pytest.mark.parametrize("case", CASES)
def test_same_events_as_the_cocotb_order(case):
    sensor_kind, period = CASES[case]
    library = harness.build(board_folder(build_root(), "fast", "verilator"), baud=VIRTUAL_BAUD)
    board_scene = _scene(sensor_kind)
    board = FastBoard(library, board_scene, baud=VIRTUAL_BAUD, seed=13, record=True)
    board.start()
    encoder = protocol.PacketEncoder()
    for name, value in (("acquisition", AcquisitionMode.RAW.value), ("delay_mode", 0),
                        ("period", period), ("aggressor", 1), ("aggressor_period", period),
                        ("aggressor_offset", 6)):
        board.harness.write(_write(encoder, name, value))
    board.harness.write(encoder.frame(PacketType.START))
    board.run(60_000)
    board.harness.write(encoder.frame(PacketType.STOP))
    board.run(200_000)                  # the raw FIFO through the UART

    # The same events as the cocotb board's order of calls gives, window by window
    reference = _replayed(board_scene, board.sensor.edges, seed=13)
    starts = sum(kind == START for _, kind in board.sensor.edges)
    assert starts > 200 and board.sensor.starts == reference.starts == starts
    assert board.sensor.fed_windows == reference.fed_windows
    assert board.sensor.fed == reference.fed and len(reference.fed) > 200
    assert (board.sensor.late > 0) == (case == "single-cut") and \
        board.sensor.late == reference.late

    # What went on the bus came back from the gateware, bit for bit
    presented = board.harness.take_presented()
    assert len(presented) + board.harness.busy_drops == len(board.sensor.fed)
    decoder = protocol.FrameDecoder(synced=True)
    packets = [item for item in decoder.feed(board.harness.read())
               if isinstance(item, protocol.Packet) and item.type == PacketType.EVENTS]
    got = np.concatenate([protocol.unpack_events(packet.payload) for packet in packets]) \
        if packets else np.zeros(0, EVENT_DTYPE)
    assert len(got) > 200
    want = np.array(presented[:len(got)], dtype=[("timestamp", "u2"), ("address", "u1"),
                                                 ("collision", "u1")])
    for name in ("timestamp", "address", "collision"):
        assert np.array_equal(got[name], want[name]), name
    # One laser cycle per window read out (the events of a window carry its pulse index)
    pulses = got["pulse"].astype(np.int64)
    assert np.all(np.diff(pulses) >= 0)
    if sensor_kind is None:
        assert len(np.unique(pulses)) == len(pulses)


def test_the_fast_engine_runs_verilator_only(capsys):
    assert main(["board", "--sim", "icarus", "--engine", "fast"]) == 1
    assert capsys.readouterr().err == ("fliss: error: the fast engine runs Verilator, not "
                                       "icarus: use --engine cocotb with --sim icarus\n")
