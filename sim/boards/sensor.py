"""The virtual board's sensor: the scene's events on the top level's sensor bus, in closed loop.

:class:`SensorModel` is what both engines of the virtual board (:mod:`.virtual`, :mod:`.fast`)
and the scene's cocotb bench put on the sensor pins; :class:`StandInPins` stands in for the pins
where no cocotb runs.

Timing of the sensor model
--------------------------
The gateware tags an event with the laser cycle in progress when the strobe is captured, so the
event of cycle ``k`` must reach the bus before the TDC start of cycle ``k + 1``. The scene
simulator only simulates a laser cycle once it knows the next TDC start (which bounds the
window); so when a window's conversion range (``2**13`` codes, 33 clock cycles at 80 MHz) has
passed without a new start, the model gives the simulator a *closing start* at that moment: a
window that records nothing, whose only effect is the SPAD dead time that photons detected
between windows carry into the next one. The event's strobe rises 35 cycles after the TDC start
and is captured 2 cycles later. A start less than 33 cycles after the previous one cuts the
window short, as in the scene model; with starts less than 38 cycles apart (PRFs above about
2 MHz) an event arrives after the next start and raw events carry that cycle's index.

Bus timing
----------
Each event takes :data:`EVENT_BUS_CYCLES` clock cycles on the bus: address, collision flag and
timestamp set, ``sensor_valid`` high one cycle later for two cycles, the bus held three cycles
more (the strobe low meanwhile). When its conversion range ends the sensor copies its TDCs into
a readout buffer and shifts the buffer out on the bus, event after event: up to one event per
window from the column, up to one per pixel that fired from a per-pixel sensor. The next
window's copy overwrites the buffer: the events not shifted out by then are lost and counted
(``busy_drops`` in the statistics file; ``SensorModel.busy_drops``). At the paper's 1 MHz PRF
(80 cycles) a window is read out 34 cycles after its TDC start and its events may start
until the next window's readout, 80 cycles later: 14 events per window fit (one every 6 cycles).

The built-in coarse TDC (``tdc_source = 1``, pin ``photon_hit``) gets no photons from the scene:
this model learns the photons of a window only once the window is over. With
``FLISS_BOARD_JUMPER`` (``laser`` or ``aggressor``) a jumper wire drives that pin from the
trigger output (:class:`~fliss.sim.boards.jumper.Jumper`, 3.2 ns after its clock edge); the
scene keeps feeding the sensor bus, which ``tdc_source = 1`` does not read.
"""

import math
import time
from collections import deque

import cocotb
from cocotb.simtime import get_sim_time
from cocotb.triggers import Event, RisingEdge, Timer

from ...hdl.clock import DEFAULT_CLOCK_HZ
from .. import scene as _scene


__all__ = ["EVENT_BUS_CYCLES", "StandInPins", "SensorModel"]


#: Clock cycles one event takes on the sensor bus (bus set, strobe one cycle later for two
#: cycles, bus held three more).
EVENT_BUS_CYCLES = 6

CLOCK_PERIOD_PS = round(1e12 / DEFAULT_CLOCK_HZ)


class StandInPins:
    """Stands in for the cocotb handle whose pins :class:`SensorModel` sets (to 0 at its
    start), where no cocotb runs: the fast board and the tests. Any pin name gives an object
    with a ``value``."""

    def __getattr__(self, name):
        pin = type("Pin", (), {"value": 0})()
        setattr(self, name, pin)
        return pin


class SensorModel:
    """Drives the sensor bus of ``dut`` from a simulation of the scene
    (:func:`~fliss.sim.scene.array.simulation_for`: one pixel, or a pixel array) in closed
    loop: its TDC starts and aggressor triggers are those the gateware emits. With ``record``,
    :attr:`fed` holds every event the scene gave, :attr:`presented` every event put on the bus
    (both as ``(timestamp, address, collision)``), :attr:`fed_windows` the number of events of
    each window read out, :attr:`edges` every TDC start and aggressor edge it was told of
    (``(cycle, 0)`` and ``(cycle, 1)``)."""

    def __init__(self, dut, scene, *, seed=None, record=False):
        self.dut = dut
        self.scene = scene
        self.simulation = _scene.simulation_for(scene, seed=seed, chunk_cycles=64,
                                                external_starts=True, external_aggressors=True)
        # Cycles after a TDC start when the sensor's conversion range is over.
        self.window_cycles = math.ceil(_scene.TDC_CODES / scene.lsb_per_cycle)
        self.starts = 0          # real TDC starts seen
        self.events = 0          # events put on the bus
        self.late = 0            # windows cut short by the next start
        self.busy_drops = 0      # events overwritten in the readout buffer, not on the bus
        self.python_s = 0.0      # real time spent in the scene simulator
        self.fed = [] if record else None
        self.presented = [] if record else None
        self.fed_windows = [] if record else None
        self.edges = [] if record else None
        self._open = None        # cycle of the last start whose window is not closed yet
        self._closing = set()    # closing starts fed and not simulated yet
        self._queue = deque()    # windows read out, each a list of events
        self._wake = Event()
        for name in ("sensor_valid", "sensor_timestamp", "sensor_address", "sensor_collision",
                     "photon_hit"):
            getattr(dut, name).value = 0

    def start(self):
        cocotb.start_soon(self._starts())
        cocotb.start_soon(self._presenter())
        if self.scene.aggressors:
            cocotb.start_soon(self._aggressor())

    @staticmethod
    def cycle():
        return round(get_sim_time("ps") / CLOCK_PERIOD_PS)

    async def _aggressor(self):
        while True:
            await RisingEdge(self.dut.aggressor_laser)
            self.on_aggressor(self.cycle())

    def on_aggressor(self, cycle):
        """A rising edge of the aggressor's trigger in clock cycle ``cycle``."""
        if self.edges is not None:
            self.edges.append((cycle, 1))
        self.simulation.feed_aggressor(0, cycle)

    async def _starts(self):
        while True:
            await RisingEdge(self.dut.tdc_start)
            cycle = self.cycle()
            self.on_start(cycle)
            cocotb.start_soon(self._close(cycle))

    async def _close(self, cycle):
        # One cycle after the window's end, so that a real start in that cycle is seen first.
        await Timer((self.window_cycles + 1) * CLOCK_PERIOD_PS, unit="ps")
        self.on_window_end(cycle)

    def on_start(self, cycle):
        """A TDC start (victim laser pulse) in clock cycle ``cycle``."""
        if self.edges is not None:
            self.edges.append((cycle, 0))
        self.starts += 1
        cut = self._open is not None
        self.simulation.feed(cycle)
        if cut:
            # The previous window ends at this start: simulate it now.
            self.late += 1
            self._emit()
        self._open = cycle

    def on_window_end(self, cycle):
        """The conversion range of the window started in ``cycle`` is over (a cycle ago)."""
        if self._open != cycle:
            return                      # a later start has cut this window already
        self._closing.add(cycle + self.window_cycles)
        self.simulation.feed(cycle + self.window_cycles, fired=False)
        self._emit()

    def _emit(self):
        began = time.perf_counter()
        try:
            self._simulate()
        finally:
            self.python_s += time.perf_counter() - began

    def _simulate(self):
        chunk = self.simulation.step()
        self._open = None
        closing = self._closing
        starts = chunk.start_cycles.tolist()
        if not len(chunk.events):
            closing.difference_update(starts)
            return
        windows = {}
        events = chunk.events
        first = chunk.first_pulse
        for pulse, event in zip(events["pulse"].tolist(), zip(
                events["timestamp"].tolist(), events["address"].tolist(),
                events["collision"].tolist())):
            index = (pulse - first) & 0xffffffff
            # Events of closing windows are photons between TDC windows: nobody records them.
            if starts[index] not in closing:
                windows.setdefault(index, []).append(event)
        closing.difference_update(starts)
        for index in sorted(windows):
            self._queue.append(windows[index])
            if self.fed is not None:
                self.fed.extend(windows[index])
                self.fed_windows.append(len(windows[index]))
        if self._queue:
            self._wake.set()

    async def _presenter(self):
        dut = self.dut
        while True:
            if not self._queue:
                self._wake.clear()
                await self._wake.wait()
                continue
            window = self._queue.popleft()
            for position, (timestamp, address, collision) in enumerate(window):
                if self._queue:
                    # The next window's readout has overwritten the buffer.
                    self.busy_drops += len(window) - position
                    break
                dut.sensor_timestamp.value = timestamp
                dut.sensor_address.value = address
                dut.sensor_collision.value = collision
                await Timer(CLOCK_PERIOD_PS, unit="ps")
                dut.sensor_valid.value = 1
                await Timer(2 * CLOCK_PERIOD_PS, unit="ps")
                dut.sensor_valid.value = 0
                self.events += 1
                if self.presented is not None:
                    self.presented.append((timestamp, address, collision))
                # Hold the bus past the capture, and the strobe low for two cycles.
                await Timer((EVENT_BUS_CYCLES - 3) * CLOCK_PERIOD_PS, unit="ps")
