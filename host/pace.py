"""How fast a board runs: its clock's seconds per second of the host's, measured.

A board on hardware runs in real time (a pace of 1); the model board too; a simulation of the
gateware (the virtual board's cocotb engine) some thousand times slower. A command that waits
for an acquisition sized for a real board would give a simulated one up as dead, and one sized
for a simulation would waste a real board's statistics: :func:`measure_pace` finds out which it
is, from the board's own count of laser pulses over a known time of the host's.

:func:`measure_pace` starts a histogram acquisition whose integration outlasts the measurement
(nothing is sent while it runs), waits :data:`PROBE_S` of the host's time, stops it and reads
how many pulses the board fired: pulses times the period over the clock frequency is the time
the board ran, the START-to-STOP time of the host's the time it took. The settings it changes
are put back; the histogram the STOP reads out is drained.
"""

import time

from ..hdl.protocol import NakCode
from ..hdl.registers import AcquisitionMode
from .errors import BoardRefused


__all__ = ["PROBE_S", "PROBE_PERIOD_CYCLES", "PROBE_BIN_SHIFT", "REAL_TIME", "measure_pace", "host_s",
           "acquire_timeout_s"]


#: Seconds of the host's time the measurement runs for.
PROBE_S = 0.5
#: The laser's period during the measurement, in cycles (a pulse every 10 µs at 80 MHz: the
#: count resolves a pace of 2e-5 and more, a simulation of 1600 cycles a second).
PROBE_PERIOD_CYCLES = 800
#: A pace above this is taken as a real-time board (the host's waits around START and STOP
#: count against the board's time: a real board measures a little under 1).
REAL_TIME = 0.5
#: Bin shift during the measurement: the histogram the STOP reads out is 256 bins, not 8192
#: (a full readout would take a simulation minutes).
PROBE_BIN_SHIFT = 8
#: The registers the measurement changes.
_CHANGED = ("acquisition", "integration", "period", "delay_mode", "aggressor", "bin_shift")


def measure_pace(board, probe_s: float = PROBE_S) -> float:
    """The board's seconds per second of the host's (1 for a board on hardware), from its count
    of laser pulses over ``probe_s`` of acquisition (see the module)."""
    client = board.client
    board.stop()
    before = client.read_registers()
    current = dict(before)
    changes = {"acquisition": AcquisitionMode.HISTOGRAM.value, "period": PROBE_PERIOD_CYCLES,
               "integration": (1 << 32) - 1, "delay_mode": 0, "aggressor": 0}
    current = client.write_registers(changes, current=current)
    try:
        current = client.write_registers({"bin_shift": PROBE_BIN_SHIFT}, current=current)
    except BoardRefused as error:       # (a build that narrows it: the readout is longer)
        if error.code != NakCode.OUT_OF_RANGE:
            raise
    try:
        started = time.monotonic()
        client.start()
        time.sleep(probe_s)
        client.stop()
        elapsed = time.monotonic() - started
        pulses = client.status()["pulses"]
    finally:
        board.stop()
        client.write_registers({name: before[name] for name in _CHANGED}, current=current)
    return pulses * PROBE_PERIOD_CYCLES / board.clock_hz / elapsed


def host_s(board_s: float, pace: float) -> float:
    """Seconds of the host's time that ``board_s`` of the board's take at ``pace``."""
    return board_s / max(pace, 1e-9)


def acquire_timeout_s(board, pace: float):
    """Seconds to wait for each histogram of the board's settings at ``pace``: None (the
    board's own :meth:`~fliss.host.board.Board.wait_s`) on a real-time board; on a slower one,
    that wait's integration and link times in the host's time at ``pace``."""
    if pace >= REAL_TIME:
        return None
    reply_s = max(2.0, board.client.timeout_s)
    return reply_s + host_s(board.wait_s() - reply_s, pace)
