"""Bit-exact model of :class:`fliss.hdl.rawfifo.RawFifo`.

An input register delays every event by one cycle; then comes a block-RAM queue of
``depth - 2`` entries, then the RAM's two read registers: the middle one (the read) and the
output register. Per cycle, the model applies the
same rules: the queue takes a write unless it holds ``depth - 2`` entries; the output register
loads the middle one's contents (an entry or nothing) whenever it is empty or being read, and
the middle one loads the oldest queued entry whenever it is empty or being moved on; the entry
loaded in a cycle is never the one written in that cycle.
"""

from collections import deque

import numpy as np

from ...hdl.rawfifo import DEPTH, COUNTER_WIDTH, check_depth


__all__ = ["check_depth", "simulate"]


def simulate(valid, ready, *, depth=DEPTH, counter_width=COUNTER_WIDTH):
    """Cycle-by-cycle model.

    Parameters
    ----------
    valid : array_like of bool
        ``events.valid`` per cycle; the ``n``-th high cycle carries event ``n``.
    ready : array_like of bool
        ``output.ready`` per cycle, at least as long as ``valid``; the model runs for
        ``len(ready)`` cycles.

    Returns
    -------
    transfers : numpy.ndarray of int64, shape (n, 2)
        Cycle and event number of each transfer on ``output``, in order.
    dropped : numpy.ndarray of int64
        Numbers of the dropped events.
    level : numpy.ndarray of int64
        ``level`` in each cycle.
    counters : dict
        Final ``accepted`` and ``dropped``, saturated at ``2**counter_width - 1``.
    """
    check_depth(depth)
    valid = np.asarray(valid, dtype=bool)
    ready = np.asarray(ready, dtype=bool)
    queue = deque()
    middle = None   # event number in the RAM's first read register
    out = None      # event number in the output register
    number = 0
    transfers, dropped, levels = [], [], []
    accepted = 0
    for cycle in range(len(ready)):
        levels.append(len(queue) + (middle is not None) + (out is not None))
        w_rdy = len(queue) != depth - 2
        if out is not None and ready[cycle]:
            transfers.append((cycle, out))
        take = out is None or bool(ready[cycle])
        if take:
            out = middle
        if len(queue) > 0 and (middle is None or take):
            middle = queue.popleft()
        elif take:
            middle = None
        if 1 <= cycle <= len(valid) and valid[cycle - 1]:  # the input register's output
            if w_rdy:
                queue.append(number)
                accepted += 1
            else:
                dropped.append(number)
            number += 1
    top = (1 << counter_width) - 1
    counters = {"accepted": min(accepted, top), "dropped": min(len(dropped), top)}
    return (np.array(transfers, dtype=np.int64).reshape(-1, 2), np.array(dropped, dtype=np.int64),
            np.array(levels, dtype=np.int64), counters)
