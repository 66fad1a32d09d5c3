"""The virtual board: the top level's generated Verilog in a simulator, behind a pseudo-terminal.

This is the cocotb test module that :mod:`fliss.host.virtual` runs in Icarus or Verilator. It

* opens a pseudo-terminal, writes the path of its slave side to the file named by
  ``FLISS_BOARD_PTY_FILE`` (written whole, then renamed, so the launcher never reads half of it),
  and carries the bytes: pty to the ``uart_rx`` pin with :class:`~fliss.sim.benches.uart_bfm.UartSource`,
  the ``uart_tx`` pin to the pty with :class:`~fliss.sim.benches.uart_bfm.UartSink`. The pty is read
  without blocking every :data:`POLL_US` microseconds of simulated time; while the board is idle
  (not acquiring, nothing to send either way) the loop also waits a little in real time, so an
  idle board takes no CPU. It keeps its own descriptor of the slave side open, so host tools can
  open and close the port as often as they like, as with a USB UART;
* feeds the sensor pins in closed loop from a :class:`~fliss.sim.scene.Simulation` of the scene
  (:mod:`fliss.sim.scene`): the victim's echo from a target ``FLISS_BOARD_TARGET_M`` metres away
  relative to each ``tdc_start`` rising edge the gateware emits, the aggressor's photons after
  each ``aggressor_laser`` rising edge (over the same path unless
  ``FLISS_BOARD_AGGRESSOR_TOF_S`` says otherwise), background light and SPAD dead time. The
  sensor keeps the last photon of each TDC window and presents it on the bus as the sensor of
  the paper does, when its conversion range ends: bus first, then ``sensor_valid`` high for two
  clock cycles, at most one event per window. With ``FLISS_BOARD_SCENE=line`` the scene is a
  pixel array (:func:`~fliss.sim.scene.pixels.line_pixels`: a wall ``FLISS_BOARD_TARGET_M``
  away, an object ``FLISS_BOARD_OBJECT_M`` away before pixels 20 to 39) seen by the sensor
  ``FLISS_BOARD_SENSOR``: ``column`` (the paper's: one event per window, the address of the
  pixel that fired last, the collision flag) or ``per_pixel`` (one TDC per pixel: a window's
  events one after the other, in address order; see *Bus timing*). The SPADs are the detector
  ``FLISS_BOARD_DETECTOR`` describes (a :class:`~fliss.sim.scene.Detector`'s fields in JSON;
  empty: the scene's default detector);
* resets the gateware (``rst`` high for :data:`RESET_CYCLES` cycles, as a power cycle or the
  reset button would: registers, counters, sequence and histogram numbers back to reset) once
  ``FLISS_BOARD_RESET_AFTER`` data packets (HISTOGRAM, EVENTS) have gone to the host, and each
  time the file ``FLISS_BOARD_RESET_FILE`` appears (it is removed; checked once a second);
* runs until the launcher (``FLISS_BOARD_PARENT_PID``) is gone, or until killed.

Python work per laser cycle is one scene step and a few triggers, nothing per clock cycle.

The sensor bus is driven by :class:`~fliss.sim.boards.sensor.SensorModel` (its timing: that
module).
"""

import json
import os
import select
import time
import tty

import cocotb
from cocotb.clock import Clock
from cocotb.simtime import get_sim_time
from cocotb.triggers import ClockCycles, Event, Timer

from ...hdl.clock import DEFAULT_CLOCK_HZ
from .. import scene as _scene
from ...protocol.frames import FrameDecoder, Packet
from ...protocol.packets import DATA_TYPES
from ..benches.uart_bfm import UartSink, UartSource
from .sensor import SensorModel


__all__ = ["POLL_US", "RESET_CYCLES", "PtyBridge", "virtual_board"]


#: Simulated time between two polls of the pseudo-terminal, in microseconds (6 bytes at 12 M
#: baud, far less than the pty's buffer; 400 clock cycles, so the poll costs nothing next to
#: the simulation, and a command waits little for it).
POLL_US = 5

#: Idle polls before the loop starts waiting in real time as well.
IDLE_POLLS = 100

#: Real time waited per poll while idle, in seconds, unless the host writes first: an idle
#: board simulates 5 µs, then sleeps (some 5 % of a core instead of all of it).
IDLE_WAIT_S = 0.1

#: Largest backlog of bytes for the host before the oldest are dropped (a host that does not
#: read loses data, as with a real USB UART).
MAX_BACKLOG = 1 << 22

#: Clock cycles ``rst`` is held high by a reset in the middle of a run.
RESET_CYCLES = 4

CLOCK_PERIOD_PS = round(1e12 / DEFAULT_CLOCK_HZ)


def env_setting(name, default, convert=float):
    """Environment variable ``name`` through ``convert``; ``default`` when unset or empty."""
    value = os.environ.get(name)
    return default if value in (None, "") else convert(value)


class PtyBridge:
    """A pseudo-terminal carrying the UART pins of ``dut``.

    :meth:`poll` moves what the host wrote to the UART driver and what the UART monitor received
    to the host, without blocking; it returns whether anything moved. With ``count_data`` it
    also decodes what goes to the host and counts the data packets (:attr:`data_packets`).
    """

    def __init__(self, dut, baud, *, count_data=False):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)          # no echo, no line editing: bytes pass unchanged
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.source = UartSource(dut.uart_rx, baud)
        self.sink = UartSink(dut.uart_tx, baud)
        self._to_board = bytearray()
        self._to_host = bytearray()
        self._wake = Event()
        self.bytes_to_board = 0
        self.bytes_to_host = 0
        self.dropped = 0
        self.data_packets = 0
        self._decoder = FrameDecoder(synced=True) if count_data else None

    def start(self):
        cocotb.start_soon(self._sender())

    async def _sender(self):
        while True:
            if not self._to_board:
                self._wake.clear()
                await self._wake.wait()
                continue
            data = bytes(self._to_board)
            self._to_board.clear()
            await self.source.send(data)

    def poll(self):
        moved = False
        while True:
            try:
                data = os.read(self.master, 1 << 16)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:             # EIO: no slave open (never, as we hold one)
                break
            if not data:
                break
            self._to_board += data
            self.bytes_to_board += len(data)
            moved = True
        if self._to_board:
            self._wake.set()
        received = self.sink.received
        if received:
            self._to_host += received
            self.bytes_to_host += len(received)
            if self._decoder is not None:
                self.data_packets += sum(
                    isinstance(item, Packet) and item.type in DATA_TYPES
                    for item in self._decoder.feed(bytes(received)))
            del received[:]
            moved = True
        if len(self._to_host) > MAX_BACKLOG:
            excess = len(self._to_host) - MAX_BACKLOG
            del self._to_host[:excess]
            self.dropped += excess
        if self._to_host:
            try:
                written = os.write(self.master, self._to_host)
                del self._to_host[:written]
            except (BlockingIOError, InterruptedError):
                pass
            except OSError:
                self.dropped += len(self._to_host)
                self._to_host.clear()
        return moved or bool(self._to_board)

    @property
    def backlog(self):
        return len(self._to_host)

    def wait(self, seconds):
        """Wait in real time until the host writes something, or ``seconds``."""
        select.select([self.master], [], [], seconds)


def publish_file(path, text):
    """Write ``text`` to ``path`` whole (through a temporary file and a rename)."""
    temporary = f"{path}.tmp"
    with open(temporary, "w") as file:
        file.write(text)
    os.replace(temporary, path)


def parent_alive(pid):
    """Whether process ``pid`` (the launching ``fliss board``) still runs; true for ``None``."""
    if pid is None:
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def scene_from_environment():
    """The scene that ``fliss board``'s options describe (``FLISS_BOARD_*``)."""
    target_m = env_setting("FLISS_BOARD_TARGET_M", 4.0)
    aggressor_tof = os.environ.get("FLISS_BOARD_AGGRESSOR_TOF_S")
    aggressor = _scene.Aggressor(
        period_cycles=80, offset_s=0.0,
        detections_per_pulse=env_setting("FLISS_BOARD_AGGRESSOR_SIGNAL", 0.05),
        tof_s=None if aggressor_tof in (None, "") else float(aggressor_tof))
    pixels = _scene.pixels_named(os.environ.get("FLISS_BOARD_SCENE") or "single",
                                 sensor=os.environ.get("FLISS_BOARD_SENSOR") or "column",
                                 wall_m=target_m, object_m=env_setting("FLISS_BOARD_OBJECT_M", 2.5))
    return _scene.Scene(
        distance_m=target_m,
        detections_per_pulse=env_setting("FLISS_BOARD_SIGNAL", 0.05),
        background_hz=env_setting("FLISS_BOARD_AMBIENT_HZ", 1e5),
        aggressors=(aggressor,), pixels=pixels,
        detector=env_setting("FLISS_BOARD_DETECTOR", None,
                             lambda text: _scene.Detector(**json.loads(text))))


async def _reset(dut):
    """The gateware's reset, as a power cycle or the reset button would do."""
    dut.rst.value = 1
    await ClockCycles(dut.clk, RESET_CYCLES)
    dut.rst.value = 0


def reset_requested(path):
    """Whether the file ``path``, a reset request, exists; it is removed, the request taken."""
    if not path:
        return False
    try:
        os.unlink(path)
    except FileNotFoundError:
        return False
    return True


def _start_loopbacks(dut, seed):
    """The jumper wire of ``FLISS_BOARD_JUMPER`` (``laser`` or ``aggressor``) on the photon pin
    (:class:`~fliss.sim.boards.jumper.Jumper`), if any; with ``FLISS_BOARD_FINE_TDC`` (a build
    of :class:`~fliss.sim.boards.fine_loopback.FineTdcTop`), the fine TDC's delay line driven
    from the model: the oscillator, the internal loopback, and that jumper."""
    jumper = os.environ.get("FLISS_BOARD_JUMPER") or None
    if jumper is not None:
        from .jumper import Jumper
        Jumper(dut, jumper, seed=seed).start()
    if os.environ.get("FLISS_BOARD_FINE_TDC") == "1":
        from .fine_loopback import FineLoopback
        FineLoopback(dut, DEFAULT_CLOCK_HZ, seed=seed, jumper=jumper).start()


@cocotb.test()
async def virtual_board(dut):
    """Serve the board on a pseudo-terminal until the launcher goes away."""
    baud = env_setting("FLISS_BOARD_BAUD", 12_000_000, int)
    seed = env_setting("FLISS_BOARD_SEED", None, int)
    parent = env_setting("FLISS_BOARD_PARENT_PID", None, int)
    pty_file = os.environ.get("FLISS_BOARD_PTY_FILE")
    stats_file = os.environ.get("FLISS_BOARD_STATS_FILE")
    reset_after = env_setting("FLISS_BOARD_RESET_AFTER", None, int)
    reset_file = os.environ.get("FLISS_BOARD_RESET_FILE")
    resets = 0

    Clock(dut.clk, CLOCK_PERIOD_PS, unit="ps", impl="gpi").start()
    dut.uart_rx.value = 1
    sensor = SensorModel(dut, scene_from_environment(), seed=seed)
    dut.rst.value = 1
    await ClockCycles(dut.clk, 4)
    dut.rst.value = 0
    await ClockCycles(dut.clk, 4)
    sensor.start()
    _start_loopbacks(dut, seed)
    bridge = PtyBridge(dut, baud, count_data=reset_after is not None)
    bridge.start()
    if pty_file:
        publish_file(pty_file, bridge.path + "\n")
    dut._log.info("virtual board on %s at %d baud", bridge.path, baud)

    idle = 0
    wall_start = last_check = time.monotonic()
    sim_start_ps = get_sim_time("ps")
    while True:
        await Timer(POLL_US, unit="us")
        if bridge.poll() or bridge.backlog or int(dut.running.value):
            idle = 0
        else:
            idle += 1
            if idle > IDLE_POLLS:
                bridge.wait(IDLE_WAIT_S)
        reset = (reset_after is not None and not resets
                 and bridge.data_packets >= reset_after)
        now = time.monotonic()
        if now - last_check >= 1.0:
            last_check = now
            reset = reset or reset_requested(reset_file)
            if not parent_alive(parent):
                dut._log.info("launcher gone: stopping")
                break
            if stats_file:
                cycles = round((get_sim_time("ps") - sim_start_ps) / CLOCK_PERIOD_PS)
                publish_file(stats_file, (
                    f'{{"wall_s": {now - wall_start:.3f}, "cycles": {cycles}, '
                    f'"bytes_to_board": {bridge.bytes_to_board}, '
                    f'"bytes_to_host": {bridge.bytes_to_host}, "dropped": {bridge.dropped}, '
                    f'"tdc_starts": {sensor.starts}, "events": {sensor.events}, '
                    f'"late_windows": {sensor.late}, "busy_drops": {sensor.busy_drops}, '
                    f'"scene_s": {sensor.python_s:.3f}, "resets": {resets}, '
                    f'"cpu_s": {time.process_time():.3f}}}\n'))
        if reset:
            resets += 1
            dut._log.info("reset %d after %d data packets to the host", resets,
                          bridge.data_packets)
            await _reset(dut)
    os.close(bridge.master)
    os.close(bridge.slave)
