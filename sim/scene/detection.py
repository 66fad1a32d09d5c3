"""The detection of the scene simulator's photons, vectorised: which span (TDC window, or the
dead time before it) each photon is in, and which photons the non-paralysable SPAD detects.
:mod:`~fliss.sim.scene.few` does the same in plain Python for a few photons.
"""

import numpy as np

from .description import TDC_CODES


__all__ = ["spans", "non_paralysable"]


def spans(times, starts, span_starts, ends, dead, separated):
    """``(span, in_span, in_window)`` of photons at ``times`` (sorted): the span each is in (the
    TDC window from ``starts[span]``, or the dead time before it), whether it is in one, and
    whether in its window. ``separated``: spans do not overlap, each its window and the dead
    time before; otherwise they run from ``span_starts`` to ``ends``."""
    if separated:
        span = np.searchsorted(starts, times + dead, side="right") - 1
        offset = times - starts[np.maximum(span, 0)]
        in_span = (span >= 0) & (offset < TDC_CODES)
        in_window = in_span & (offset >= 0)
    else:
        span = np.searchsorted(span_starts, times, side="right") - 1
        clipped = np.maximum(span, 0)
        in_span = (span >= 0) & (times < ends[clipped])
        in_window = in_span & (times >= starts[clipped])
    return span, in_span, in_window


def non_paralysable(times, dead, last):
    """Which photons (sorted ``times``) a non-paralysable detector detects; ``last`` is the time
    of the last detection before them."""
    count = len(times)
    if count == 0 or dead <= 0:
        return np.ones(count, dtype=bool)
    previous = np.empty(count)
    previous[0] = last
    previous[1:] = times[:-1]
    # A photon at least one dead time after the previous photon is detected whatever happened
    # before. The others sit in clusters behind such a photon and are resolved in order, one
    # position of all clusters at a time.
    detected = (times - previous) >= dead
    if detected.all():
        return detected
    heads = np.maximum.accumulate(np.where(detected, np.arange(count), -1))
    open_ = np.flatnonzero(~detected)
    head = heads[open_]
    clusters, cluster = np.unique(head, return_inverse=True)
    reference = np.where(clusters >= 0, times[np.maximum(clusters, 0)], last)
    position = open_ - head
    order = np.argsort(position, kind="stable")
    bounds = np.searchsorted(position[order], np.arange(1, position.max() + 2))
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        members = order[lo:hi]
        index = open_[members]
        owner = cluster[members]
        ok = times[index] - reference[owner] >= dead
        detected[index] = ok
        reference[owner[ok]] = times[index[ok]]
    return detected
