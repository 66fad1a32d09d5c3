"""Bit-exact model of :class:`fliss.hdl.rawfifo.RawFifo`.

An input register delays every event by one cycle; then comes
:class:`amaranth.lib.fifo.SyncFIFOBuffered`: a block-RAM queue of ``depth - 1`` entries followed by
an output register. Per cycle, the model applies the same rules: the queue
takes a write unless it holds ``depth - 1`` entries; the output register loads the oldest queued
entry whenever it is empty or being read; the entry loaded in a cycle is never the one written in
that cycle.
"""

from collections import deque

import numpy as np

from ..hdl.rawfifo import DEPTH, COUNTER_WIDTH


__all__ = ["check_depth", "simulate"]


def check_depth(depth):
    """Raise :exc:`ValueError` unless ``depth`` is a valid FIFO depth."""
    if not isinstance(depth, (int, np.integer)) or depth < 3:
        raise ValueError(f"FIFO depth must be an integer of at least 3, not {depth!r}")


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
    out = None  # event number in the output register
    number = 0
    transfers, dropped, levels = [], [], []
    accepted = 0
    for cycle in range(len(ready)):
        levels.append(len(queue) + (out is not None))
        w_rdy = len(queue) != depth - 1
        r_en = bool(ready[cycle])
        r_rdy = out is not None
        if r_rdy and r_en:
            transfers.append((cycle, out))
        inner_read = len(queue) > 0 and (not r_rdy or r_en)
        if inner_read:
            out = queue.popleft()
        elif r_en:
            out = None
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
