"""The Python model board's STATUS against the gateware's rules."""

import time

from fliss.host.client import BoardClient
from fliss.sim.model_board import model_board


def test_pulse_count_restarts_with_each_start():
    # The gateware's scheduler restarts its pulse index on every START (hdl/scheduler.py), so
    # STATUS `pulses` counts the pulses of the running acquisition only.
    with model_board() as model, BoardClient(model.path, timeout_s=2.0) as board:
        board.start()
        time.sleep(0.3)
        first = board.status()["pulses"]
        board.stop()
        board.start()
        again = board.status()["pulses"]
        board.stop()
    assert first > 0
    assert again < first
