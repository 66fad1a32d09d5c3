"""The fast virtual board: the top level in the C++ harness (:mod:`.harness`), the scene
simulator on its sensor pins, the UART behind a pseudo-terminal.

It is the cocotb virtual board (:mod:`fliss.sim.boards.virtual`) without cocotb: the same
environment (``FLISS_BOARD_*``), the same pty, statistics and reset files, and the same sensor
model (:class:`~fliss.sim.boards.sensor.SensorModel`, fed with the same TDC starts, aggressor
edges and window ends in the same order, so one seed gives the same events). The harness does
the per-cycle work in C++: clocking, the UART pins, the edges, shifting events out on the bus;
Python runs only when something happens: a TDC start or aggressor edge, a window's conversion
range ending, every :data:`~fliss.sim.boards.virtual.POLL_US` of simulated time for the pty.

``python -m fliss.sim.boards.fast LIBRARY`` runs it (:mod:`fliss.host.virtual` does) with the
harness library built by :func:`fliss.sim.boards.harness.build`.
"""

import logging
import os
import sys
import time
from collections import deque

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...protocol.frames import FrameDecoder, Packet
from ...protocol.packets import DATA_TYPES
from .harness import Harness
from .sensor import SensorModel, StandInPins
from .virtual import (IDLE_POLLS, IDLE_WAIT_S, MAX_BACKLOG, POLL_US, RESET_CYCLES, env_setting,
                      parent_alive, publish_file, reset_requested, scene_from_environment)
from .pty_server import close_pty

import select
import tty


__all__ = ["POLL_CYCLES", "FastBoard", "main"]


logger = logging.getLogger("fliss.board")

#: Clock cycles between two polls of the pty (as the cocotb board's POLL_US).
POLL_CYCLES = round(POLL_US * 1e-6 * DEFAULT_CLOCK_HZ)

#: Kind of an edge the harness records.
START, AGGRESSOR = 0, 1


class FastBoard:
    """The top level in the harness ``library``, its sensor fed from ``scene`` with ``seed``.

    With ``record``, ``sensor.edges`` keeps every edge told to the sensor model (``(cycle,
    kind)``, kind :data:`START` or :data:`AGGRESSOR`), ``sensor.fed`` every event the scene
    gave, and ``harness.take_presented()`` gives the events put on the bus."""

    def __init__(self, library, scene, *, baud, seed=None, record=False):
        self.harness = Harness(library, DEFAULT_CLOCK_HZ / baud, record=record)
        self.sensor = SensorModel(StandInPins(), scene, seed=seed, record=record)
        self._closes = deque()      # (cycle, start): window ends to tell the sensor model
        self._reset_until = None
        self.resets = 0

    def start(self):
        """The power-on reset, as the cocotb board: ``rst`` for 4 cycles, then 4 cycles."""
        self.harness.set_reset(1)
        self.harness.run(4)
        self.harness.set_reset(0)
        self.harness.run(8)

    def reset(self):
        """The gateware's reset (``rst`` for RESET_CYCLES cycles) from the next cycle on."""
        self.harness.set_reset(1)
        self._reset_until = self.harness.cycle + RESET_CYCLES
        self.resets += 1

    def run(self, cycles):
        """Clock the board ``cycles`` cycles, the sensor model in closed loop."""
        harness, sensor, closes = self.harness, self.sensor, self._closes
        target = harness.cycle + cycles
        window_cycles = sensor.window_cycles
        while harness.cycle < target:
            until = target
            if self._reset_until is not None and self._reset_until < until:
                until = self._reset_until
            # The harness stops where the sensor model simulates a window (a start that cuts
            # one, a window's end); what came before is told in order, as the cocotb board
            # sees it: in one cycle, starts, aggressor edges, then window ends.
            for cycle, kind in zip(*harness.run_edges(until, window_cycles)):
                while closes and closes[0][0] < cycle:
                    sensor.on_window_end(closes.popleft()[1])
                if kind == START:
                    sensor.on_start(cycle)
                    closes.append((cycle + window_cycles + 1, cycle))
                else:
                    sensor.on_aggressor(cycle)
            while closes and closes[0][0] <= harness.cycle:
                sensor.on_window_end(closes.popleft()[1])
            while sensor._queue:
                harness.window(sensor._queue.popleft())
            if self._reset_until is not None and harness.cycle >= self._reset_until:
                harness.set_reset(0)
                self._reset_until = None


def main(argv=None):
    """Serve the board on a pseudo-terminal until the launcher goes away (the environment of
    :mod:`fliss.sim.boards.virtual`); ``argv``: the path of the harness library."""
    argv = sys.argv[1:] if argv is None else argv
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    baud = env_setting("FLISS_BOARD_BAUD", 12_000_000, int)
    parent = env_setting("FLISS_BOARD_PARENT_PID", None, int)
    pty_file = os.environ.get("FLISS_BOARD_PTY_FILE")
    stats_file = os.environ.get("FLISS_BOARD_STATS_FILE")
    reset_after = env_setting("FLISS_BOARD_RESET_AFTER", None, int)
    reset_file = os.environ.get("FLISS_BOARD_RESET_FILE")
    board = FastBoard(argv[0], scene_from_environment(), baud=baud,
                      seed=env_setting("FLISS_BOARD_SEED", None, int))
    board.start()
    harness = board.harness
    master, slave = os.openpty()
    tty.setraw(slave)               # no echo, no line editing: bytes pass unchanged
    os.set_blocking(master, False)
    path = os.ttyname(slave)
    if pty_file:
        publish_file(pty_file, path + "\n")
    logger.info("virtual board (fast harness) on %s at %d baud", path, baud)
    to_host = bytearray()
    decoder = FrameDecoder(synced=True) if reset_after is not None else None
    counts = dict(bytes_to_board=0, bytes_to_host=0, dropped=0, data_packets=0)
    idle = 0
    wall_start = last_check = time.monotonic()
    first_cycle = harness.cycle
    try:
        while True:
            board.run(POLL_CYCLES)
            moved = _carry(master, harness, to_host, decoder, counts)
            if moved or to_host or harness.running:
                idle = 0
            else:
                idle += 1
                if idle > IDLE_POLLS:
                    select.select([master], [], [], IDLE_WAIT_S)
            reset = (reset_after is not None and not board.resets
                     and counts["data_packets"] >= reset_after)
            now = time.monotonic()
            if now - last_check >= 1.0:
                last_check = now
                reset = reset or reset_requested(reset_file)
                if not parent_alive(parent):
                    logger.info("launcher gone: stopping")
                    break
                if stats_file:
                    publish_file(stats_file, _stats(board, counts, now - wall_start,
                                                harness.cycle - first_cycle))
            if reset:
                logger.info("reset %d after %d data packets to the host", board.resets + 1,
                            counts["data_packets"])
                board.reset()
    finally:
        close_pty(master, slave)
    return 0


def _carry(master, harness, to_host, decoder, counts):
    """Move bytes between the pty and the UART queues; returns whether any moved."""
    moved = False
    while True:
        try:
            data = os.read(master, 1 << 16)
        except OSError:             # nothing to read (or no slave open: never, we hold one)
            break
        if not data:
            break
        harness.write(data)
        counts["bytes_to_board"] += len(data)
        moved = True
    moved = moved or harness.to_board > 0
    received = harness.read()
    if received:
        to_host += received
        counts["bytes_to_host"] += len(received)
        if decoder is not None:
            counts["data_packets"] += sum(isinstance(item, Packet) and item.type in DATA_TYPES
                                          for item in decoder.feed(received))
        moved = True
    if len(to_host) > MAX_BACKLOG:
        excess = len(to_host) - MAX_BACKLOG
        del to_host[:excess]
        counts["dropped"] += excess
    if to_host:
        try:
            del to_host[:os.write(master, to_host)]
        except (BlockingIOError, InterruptedError):
            pass
        except OSError:
            counts["dropped"] += len(to_host)
            to_host.clear()
    return moved


def _stats(board, counts, wall_s, cycles):
    sensor, harness = board.sensor, board.harness
    return (f'{{"wall_s": {wall_s:.3f}, "cycles": {cycles}, '
            f'"bytes_to_board": {counts["bytes_to_board"]}, '
            f'"bytes_to_host": {counts["bytes_to_host"]}, "dropped": {counts["dropped"]}, '
            f'"tdc_starts": {sensor.starts}, "events": {harness.presented}, '
            f'"late_windows": {sensor.late}, "busy_drops": {harness.busy_drops}, '
            f'"scene_s": {sensor.python_s:.3f}, "resets": {board.resets}, '
            f'"cpu_s": {time.process_time():.3f}}}\n')


if __name__ == "__main__":
    raise SystemExit(main())
