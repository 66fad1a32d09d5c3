"""cocotb testbench: the virtual board's sensor model feeding the line scene to the top level.

The sensor model of the virtual board (:class:`fliss.sim.boards.sensor.SensorModel`) drives the
sensor pins of :class:`fliss.hdl.top.FlissTop` in closed loop from the line scene (60 pixels, a
wall at 4 m, an object at 2.5 m before pixels 20 to 39, a flash aggressor 75 ns after the
victim), with the column sensor or one TDC per pixel. In raw mode every event the model put on
the bus must come back in the EVENTS packets, bit for bit and in order (timestamp, pixel
address, collision flag), and every event the scene gave is either on the bus or counted as
overwritten in the sensor's readout buffer.

``FLISS_TB_CASE`` chooses one of :data:`CASES`: ``column``, ``per_pixel``, or ``burst`` (one
TDC per pixel at 1 MHz with more events per window than the bus carries before the next
window's readout: some are overwritten, and counted); the baud rate is ``FLISS_TB_BAUD``. With
``FLISS_TB_RECORD`` set to a path, the run writes there, as JSON, the edges the sensor model
was told of and the events the scene gave (``edges``, ``fed``, ``fed_windows``), for a
comparison with the fast virtual board (``tests/boards/test_cocotb_scene.py``).
"""

import json
import os

import cocotb
import numpy as np
from cocotb.triggers import ClockCycles, Timer

from ...hdl.protocol import PacketType
from ...hdl.registers import AcquisitionMode
from ... import protocol
from ...protocol.events import EVENT_DTYPE
from ..scene import Aggressor, Scene, line_pixels
from .top import TopTB
from ..boards.sensor import SensorModel


#: Per case: sensor kind, laser period (clock cycles), echo and aggressor detections per pulse
#: and pixel, length of the run (µs). The raw events must fit through the UART (about 0.15
#: events per microsecond at 12 Mbaud) and the raw FIFO (512).
CASES = {"column": ("column", 800, 0.05, 0.03, 900),
         "per_pixel": ("per_pixel", 2400, 0.05, 0.03, 900),
         "burst": ("per_pixel", 80, 0.4, 0.0, 20)}
CASE = os.environ.get("FLISS_TB_CASE", "column")
SENSOR, PERIOD, SIGNAL, AGGRESSOR, RUN_US = CASES[CASE]

#: The model's seed.
SEED = 11


def case_scene(case):
    """The scene of case ``case``."""
    sensor, period, signal, aggressor, _ = CASES[case]
    return Scene(detections_per_pulse=signal, background_hz=1e4,
                 pixels=line_pixels(sensor=sensor),
                 aggressors=(Aggressor(period_cycles=period, offset_s=0.0,
                                       detections_per_pulse=aggressor),))


def case_registers(case):
    """The registers the case writes before START, in order: ``(name, value)``."""
    period = CASES[case][1]
    return (("acquisition", AcquisitionMode.RAW.value), ("delay_mode", 0), ("period", period),
            ("aggressor", 1), ("aggressor_period", period), ("aggressor_offset", 6))


async def _start(dut):
    tb = TopTB(dut)
    tb.data_packets = []            # (a class attribute of TopTB: one list per test here)
    await tb.start()
    return tb


@cocotb.test()
async def test_line_scene_events(dut):
    """Raw events of the line scene come back with the addresses and collision flags the
    sensor model put on the bus."""
    tb = await _start(dut)
    period = PERIOD
    sensor = SensorModel(dut, case_scene(CASE), seed=SEED, record=True)
    sensor.start()
    for name, value in case_registers(CASE):
        await tb.write(**{name: value})
    await tb.command(PacketType.START)
    await Timer(RUN_US, unit="us")
    await tb.command(PacketType.STOP)
    # The last window's events, then the raw FIFO through the UART
    await ClockCycles(dut.clk, period)
    deadline = 3000
    while deadline > 0:
        await Timer(100, unit="us")
        deadline -= 100
        tb._drain()
        got = _events(tb)
        if len(got) >= len(sensor.presented) - (await tb.status())["dropped_stopped"]:
            break
    status = await tb.status()
    got = _events(tb)
    if os.environ.get("FLISS_TB_RECORD"):
        with open(os.environ["FLISS_TB_RECORD"], "w") as file:
            json.dump({"edges": sensor.edges, "fed": sensor.fed,
                       "fed_windows": sensor.fed_windows}, file)
    presented = np.array(sensor.presented, dtype=[("timestamp", "u2"), ("address", "u1"),
                                                  ("collision", "u1")])
    dut._log.info("%s: %d windows, %d events fed, %d on the bus, %d overwritten, %d back; "
                  "status %s", CASE, sensor.starts, len(sensor.fed), len(presented),
                  sensor.busy_drops, len(got),
                  {name: value for name, value in status.items() if value})
    # Every event the scene gave went on the bus or was counted as overwritten
    assert len(presented) + sensor.busy_drops == len(sensor.fed)
    assert (sensor.busy_drops > 0) == (CASE == "burst")
    # What the gateware took, bit for bit, in order; the rest came after STOP and is counted
    assert status["dropped_fifo"] == 0 and status["dropped_overrun"] == 0
    assert len(got) == status["events"] == len(presented) - status["dropped_stopped"]
    want = presented[:len(got)]
    for name in ("timestamp", "address", "collision"):
        assert np.array_equal(got[name], want[name]), (name, got[name][:8], want[name][:8])
    # Events of the line's pixels, from the object (pixels 20 to 39) and the wall
    addresses = got["address"].astype(int)
    assert len(got) > 60 and set(addresses) <= set(range(60))
    assert np.any((addresses >= 20) & (addresses < 40))
    assert np.any((addresses < 20) | (addresses >= 40))
    pulses = got["pulse"].astype(np.int64)
    if CASE == "burst":
        # The bus starts an event every 6 cycles from one window's readout to the next, 80
        # cycles later: at most 14 per window (the last window's, with no readout after it, all)
        assert len(presented) <= 14 * (len(sensor.fed_windows) - 1) + sensor.fed_windows[-1]
        assert not got["collision"].any()
    elif SENSOR == "column":
        # One event per laser cycle; the flash aggressor's 40 wall pixels often collide
        assert len(np.unique(pulses)) == len(pulses)
        assert got["collision"].sum() > 0
    else:
        # Several events per laser cycle, in address order, never a collision
        assert np.bincount(pulses).max() > 1 and not got["collision"].any()
        same = np.diff(pulses) == 0
        assert np.all(np.diff(addresses)[same] > 0)
    assert {name for name, value in status.items() if value} <= {
        "pulses", "events", "dropped_stopped", "commands"}


def _events(tb):
    pieces = [protocol.unpack_events(packet.payload) for packet in tb.data_packets + tb.packets
              if packet.type == PacketType.EVENTS]
    return np.concatenate(pieces) if pieces else np.zeros(0, EVENT_DTYPE)

