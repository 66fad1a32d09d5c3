"""A macro-pixel of ``n`` SPADs, its coincidence gate and its TDC, vectorised over a frame.

* **SPADs.** The photons that reach the macro-pixel (echo, aggressors, ambient light) fall on
  its ``n`` SPADs uniformly; each SPAD has the scene's :class:`~fliss.sim.scene.Detector`: its
  dead time (paralysable or not, each SPAD its own), timing tail, afterpulses and crosstalk
  to its neighbours (the SPADs on a grid of ``ceil(sqrt(n))`` columns): several SPADs through
  the same functions as the scene simulator (:func:`~fliss.sim.scene.avalanches.pixel_avalanches`,
  :class:`~fliss.sim.scene.avalanches.Avalanches`); one SPAD (no neighbours, no crosstalk)
  through a path of its own that draws every possible afterpulse ahead and never sorts again
  (:func:`_one_spad`, twice as fast, held to the same closed forms). The whole frame is drawn,
  gaps between windows included, so the dead time carries from every photon.
* **Coincidence** (``k`` of ``n`` within ``window``): each SPAD's count is a pulse of length
  ``window``; the gate fires when the number of SPADs whose pulse is high rises to ``k``, at
  the time of that ``k``-th count. With ``k = 1`` every count passes. The window is at most the
  dead time, so a SPAD counts at most once within it.
* **Correlation** (the ``code`` scheme): the histogram summed over the shifts of the chips.
* **TDC.** Window ``i`` runs from start ``i`` for ``length`` LSBs or until the next start. A
  single-hit TDC keeps one event per window (the last, as the paper's sensor, or the first);
  a multi-hit TDC keeps every event.
"""

import math

import numpy as np

from ...scene.avalanches import Avalanches, pixel_avalanches
from ...scene.detection import non_paralysable
from ....hdl.event import TDC_LSB_S


__all__ = ["grid_neighbours", "avalanches", "coincidences", "tdc", "correlate"]


def grid_neighbours(n):
    """``(orthogonal, diagonal)`` neighbours of ``n`` SPADs on a grid of ``ceil(sqrt(n))``
    columns (as :meth:`fliss.sim.scene.PixelArray.neighbours`: ``-1`` for none)."""
    columns = max(1, math.ceil(math.sqrt(n)))
    row, column = np.divmod(np.arange(n), columns)
    tables = []
    for steps in (((-1, 0), (1, 0), (0, -1), (0, 1)), ((-1, -1), (-1, 1), (1, -1), (1, 1))):
        table = np.full((n, 4), -1, dtype=np.int64)
        for at, (down, right) in enumerate(steps):
            r, c = row + down, column + right
            index = r * columns + c
            inside = (r >= 0) & (c >= 0) & (c < columns) & (index < n)
            table[inside, at] = index[inside]
        tables.append(table)
    return tuple(tables)


def _whole_frame(times):
    count = len(times)
    return np.zeros(count, dtype=np.int64), np.ones(count, dtype=bool), np.ones(count, dtype=bool)


def _counted(times, spad, n, dead):
    """Which photons (sorted ``times``) the ``n`` non-paralysable SPADs count."""
    if n == 1:
        return non_paralysable(times, dead, -np.inf)
    if n > 8:
        return pixel_avalanches(times, spad, np.full(n, -np.inf), dead, False)[1]
    counted = np.empty(len(times), dtype=bool)
    for one in range(n):
        mine = spad == one
        counted[mine] = non_paralysable(times[mine], dead, -np.inf)
    return counted


def _late(times, sources, detector, rng):
    """``(times, sources)`` in time order with the diffusion tail: a ``tail_fraction`` of the
    pulsed sources' photons (all but source 1) later by an exponential of mean ``tail_s``."""
    pulsed = np.flatnonzero(sources != 1)
    late = pulsed[rng.random(len(pulsed)) < detector.tail_fraction]
    if not len(late):
        return times, sources
    moved = times[late] + rng.standard_exponential(len(late)) * (detector.tail_s / TDC_LSB_S)
    keep = np.ones(len(times), dtype=bool)
    keep[late] = False
    return _merged((times[keep], sources[keep]), (moved, sources[late]))


def _merged(ordered, extra):
    """Two pairs ``(times, sources)``, the first in time order, merged in time order."""
    order = np.argsort(extra[0], kind="stable")
    times, sources = extra[0][order], extra[1][order]
    at = np.searchsorted(ordered[0], times, side="right") + np.arange(len(times))
    rest = np.ones(len(ordered[0]) + len(times), dtype=bool)
    rest[at] = False
    merged = []
    for old, new in zip(ordered, (times, sources)):
        both = np.empty(len(rest), dtype=np.result_type(old, new))
        both[at] = new
        both[rest] = old
        merged.append(both)
    return tuple(merged)


def _one_spad(times, sources, detector, rng, child_source):
    """The counts of one SPAD with afterpulses (no neighbours: no crosstalk), ``times`` sorted.

    Every photon's possible afterpulse is drawn ahead, and each afterpulse's own (a chain each,
    geometric), so that the photons never need sorting again: a photon is there when it has no
    parent or its parent is an avalanche (counted, non-paralysable; any that arrives,
    paralysable), and the counts are resolved again until that stops changing (a child comes
    after its parent, so the passes settle)."""
    dead = detector.dead_time_s / TDC_LSB_S
    probability = detector.afterpulse_probability
    means = np.array(detector.afterpulse_s) / TDC_LSB_S
    cumulative = np.cumsum(detector.afterpulse_weights)
    parent = np.full(len(times), -1, dtype=np.int64)
    generation = np.arange(len(times))
    pool_times, pool_sources, parents = [times], [sources], [parent]
    offset = len(times)
    while len(generation) and probability > 0:
        has = generation[rng.random(len(generation)) < probability]
        if not len(has):
            break
        kind = np.minimum(np.searchsorted(cumulative, rng.random(len(has)), side="right"),
                          len(means) - 1)
        base = np.concatenate(pool_times)[has]
        pool_times.append(base + means[kind] * rng.standard_exponential(len(has)))
        pool_sources.append(np.full(len(has), child_source, dtype=np.int16))
        parents.append(has)
        generation = offset + np.arange(len(has))
        offset += len(has)
    all_times, all_sources = np.concatenate(pool_times), np.concatenate(pool_sources)
    parent = np.concatenate(parents)
    order = np.argsort(all_times, kind="stable")
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    all_times, all_sources = all_times[order], all_sources[order]
    parent = np.where(parent[order] >= 0, rank[np.maximum(parent[order], 0)], -1)
    child = parent >= 0
    present = ~child
    while True:
        at = np.flatnonzero(present)
        if detector.paralysable:
            avalanche = present
            gaps = np.diff(all_times[at], prepend=-np.inf)
            counted = np.zeros(len(all_times), dtype=bool)
            counted[at[gaps >= dead]] = True
        else:
            counted = np.zeros(len(all_times), dtype=bool)
            counted[at[non_paralysable(all_times[at], dead, -np.inf)]] = True
            avalanche = counted
        now = ~child
        now[child] = avalanche[parent[child]] & present[parent[child]]
        if np.array_equal(now, present):
            return all_times[counted], all_sources[counted]
        present = now


def avalanches(times, sources, spad, detector, n, rng, first_child_source):
    """The counts of the SPADs: ``(times, sources)`` in time order of the photons (and their
    afterpulses and crosstalk) that the SPADs count. ``times`` in LSBs, in time order, ``spad``
    the SPAD of each photon; ``sources`` as the scene numbers them (1: background, else
    pulsed)."""
    dead = detector.dead_time_s / TDC_LSB_S
    if not detector.avalanche_effects:
        counted = _counted(times, spad, n, dead)
        return times[counted], sources[counted]
    if n == 1:
        times, sources = _late(times, sources, detector, rng)
        return _one_spad(times, sources, detector, rng, first_child_source)
    neighbours = grid_neighbours(n) if n > 1 else None
    effects = Avalanches(detector, rng.spawn(4), neighbours, first_child_source)
    times = effects.tail(times, sources, 0)
    order = np.argsort(times, kind="stable")
    (times, sources, _, _, _, counted), _ = effects.resolve(
        times[order], sources[order], spad[order], _whole_frame, np.full(n, -np.inf), np.inf)
    return times[counted], sources[counted]


def coincidences(times, k, window):
    """Which counts (``times`` sorted, LSBs) fire a ``k``-of-``n`` gate of ``window`` LSBs: those
    at which the number of counts in ``(t - window, t]`` is exactly ``k``."""
    if k == 1:
        return np.ones(len(times), dtype=bool)
    inside = np.arange(len(times)) - np.searchsorted(times, times - window, side="right") + 1
    return inside == k


def tdc(times, starts, length, *, keep="last", multi=False):
    """``(index, offset)`` of the events (``times`` sorted) a TDC records: the event's index in
    ``times`` and its time after its window's start, LSBs. ``starts`` increasing; window ``i``
    ends ``length`` after its start or at the next start."""
    span = np.searchsorted(starts, times, side="right") - 1
    clipped = np.maximum(span, 0)
    ends = starts + length
    ends[:-1] = np.minimum(ends[:-1], starts[1:])
    inside = np.flatnonzero((span >= 0) & (times < ends[clipped]))
    if not multi and len(inside):
        owner = span[inside]
        chosen = np.ones(len(inside), dtype=bool)
        if keep == "last":
            chosen[:-1] = owner[1:] != owner[:-1]
        else:
            chosen[1:] = owner[1:] != owner[:-1]
        inside = inside[chosen]
    return inside, times[inside] - starts[span[inside]]


def correlate(raw, chips, length):
    """The correlation of a histogram ``raw`` with a code whose chips start ``chips`` codes
    after the burst: ``length`` values, value ``t`` the sum of ``raw[t + chip]`` over the chips
    (``raw`` at least ``length + max(chips)`` long)."""
    return sum(raw[chip:chip + length] for chip in chips)
