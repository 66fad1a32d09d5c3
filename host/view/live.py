"""A board watched without a file: :func:`watch` starts it at its settings and hands a
:class:`~fliss.host.view.feed.Feed` everything it sends until told to stop (``fliss view
--port``). ``fliss capture --view`` feeds the view from the capture instead
(:func:`fliss.host.acquisition.capture`'s ``watch``)."""

import math
import time

from ..acquisition import DATA_TIMEOUT_S, HEARTBEAT_S, check_reset
from ..board import Board
from ..errors import BoardLost
from ..keyed import refuse_used_up
from .feed import Feed


__all__ = ["watch"]


def watch(board: Board, feed: Feed, *, should_stop=lambda: False) -> str:
    """Start ``board`` in its readout and feed ``feed`` until ``should_stop()`` (asked between
    packets, at least every 50 ms) or Ctrl-C; the board is stopped at the end. Returns how it
    ended (``"stopped"``); raises :exc:`~fliss.host.errors.BoardLost` (or
    :exc:`~fliss.host.errors.BoardReset`) when the board goes, after telling the feed."""
    client = board.client
    integration_s = feed.setup.integration_s
    framed = feed.setup.kind.framed
    client.stop()
    client.drain(quiet_s=0.1, limit_s=2.0)
    client.reset_counters()
    before = dict(client.status(), pulses=None)
    refuse_used_up(client.read_registers(), before)     # (a keyed run that would fire nothing)
    client.start()
    feed.add_status(before, client.link_counters())
    heartbeat = time.monotonic()
    # As a capture: a framed readout that stops sending is lost; raw readout may be quiet.
    idle_s = max(3.0, 3 * integration_s + 1.0) if framed else math.inf
    data_s = max(DATA_TIMEOUT_S, 10 * integration_s) if framed else math.inf
    try:
        for item in client.stream(idle_timeout_s=idle_s, data_timeout_s=data_s):
            if item is not None:
                feed.add(item)
            if should_stop():
                break
            now = time.monotonic()
            if now - heartbeat >= HEARTBEAT_S:
                heartbeat = now
                status = client.status()
                check_reset(client, before, status)
                before = status
                feed.add_status(status, client.link_counters())
    except BoardLost as error:
        feed.finish(f"board lost: {error}")
        raise
    except BaseException:
        feed.finish("stopped")
        _stop_quietly(client)
        raise
    feed.finish("stopped")
    _stop_quietly(client)
    return "stopped"


def _stop_quietly(client):
    try:
        client.stop()
        client.drain(quiet_s=0.1, limit_s=2.0)
    except BoardLost:
        pass
