"""The detector path of a step with few photons of one pixel, in plain Python.

In closed loop (the virtual boards) a step is one TDC window: a handful of photons, where
numpy's cost per call outweighs the work of :class:`~fliss.sim.scene.avalanches.Avalanches`
(some hundred calls a step with afterpulses). :func:`resolve_few` does what
:meth:`Avalanches.tail <fliss.sim.scene.avalanches.Avalanches.tail>` and
:meth:`Avalanches.resolve <fliss.sim.scene.avalanches.Avalanches.resolve>` do for one pixel
(no crosstalk): the same passes, taking the same draws in the same order (``Ahead.list``
gives the values ``Ahead.array`` gives), with the same float64 arithmetic on Python floats
(the logarithms of the delays through numpy, as there), so it gives the same avalanches,
children and carried photons, bit for bit. :func:`tdc_few` keeps the TDC's detections and
counts the photons as :meth:`~fliss.sim.scene.avalanches.DetectorPath._detector_step` does.
``tests/models/test_few_avalanches.py`` runs both paths on the same draws.
"""

from bisect import bisect_right
import math

import numpy as np

from .description import COUNTERS, TDC_CODES


__all__ = ["resolve_few", "tdc_few"]


_GENERATED, _OUTSIDE, _DEAD, _OVERWRITTEN, _RECORDED = range(len(COUNTERS))


def _tail(effects, times, sources, first):
    """:meth:`Avalanches.tail` on lists (``times`` changed in place)."""
    fraction, mean = effects._tail
    if fraction <= 0 or len(times) <= first:
        return
    index = [at for at in range(first, len(times)) if sources[at] != 1]
    if not index:
        return
    count = len(index)
    draws = effects._tail_draws.list(2 * count)
    late = [at for at in range(count) if draws[at] < fraction]
    if late:
        logs = np.log1p(-np.array([draws[count + at] for at in late])).tolist()
        for at, log in zip(late, logs):
            times[index[at]] -= mean * log


def _children(effects, times, parents):
    """The afterpulses of the avalanches ``parents`` (indices): ``(time, source, parent)``."""
    probability, cumulative, means, source = effects._after
    draws = effects._after_draws.list(3 * len(parents))
    has = [at for at in range(len(parents)) if draws[3 * at] < probability]
    if not has:
        return []
    cumulative, means = cumulative.tolist(), means.tolist()
    logs = np.log1p(-np.array([draws[3 * at + 2] for at in has])).tolist()
    children = []
    for at, log in zip(has, logs):
        kind = min(bisect_right(cumulative, draws[3 * at + 1]), len(means) - 1)
        owner = parents[at]
        children.append((times[owner] - means[kind] * log, source, owner))
    return children


def _avalanches(times, last, dead, paralysable):
    """:func:`~fliss.sim.scene.avalanches.pixel_avalanches` of one pixel, on lists."""
    count = len(times)
    if count == 0 or dead <= 0:
        return [True] * count, [True] * count
    if paralysable:
        counted, previous = [], last
        for time in times:
            counted.append(time - previous >= dead)
            previous = time
        return [True] * count, counted
    # The keys of pixel_avalanches' one axis (pixel 0: its offsets add nothing), in its order
    origin = times[0]
    keys = [max(last - origin, -2.0 * dead)] + [time - origin for time in times]
    order = sorted(range(count + 1), key=keys.__getitem__)
    result = [False] * (count + 1)
    reference = -math.inf
    for at in order:
        if keys[at] - reference >= dead:
            result[at] = True
            reference = keys[at]
    counted = result[1:]
    return counted, counted


def _locate(time, windows):
    """``(span, in_span, in_window)`` of one photon, as :func:`~fliss.sim.scene.detection.spans`
    with spans that touch (``windows``: ``(starts, span_starts, ends)``, lists)."""
    starts, span_starts, ends = windows
    span = bisect_right(span_starts, time) - 1
    clipped = max(span, 0)
    in_span = span >= 0 and time < ends[clipped]
    return span, in_span, in_span and time >= starts[clipped]


def resolve_few(effects, times, sources, carried, windows, last, boundary):
    """A step's photons of one pixel through the detector's effects (``effects``: the step's
    :class:`~fliss.sim.scene.avalanches.Avalanches`): ``times`` and ``sources`` (lists, not
    sorted; the first ``carried`` carried over), ``windows`` as :func:`_locate` takes them,
    ``last`` the pixel's last avalanche. Returns the photons before ``boundary`` with their
    children in time order, ``(times, sources, located, counted)`` (``located``: each one's
    ``(span, in_span, in_window)``), the photons and children carried over (``(times,
    sources)``) and the last avalanche."""
    times, sources = list(times), list(sources)
    _tail(effects, times, sources, carried)
    carry = [at for at in range(len(times)) if times[at] >= boundary]
    carry_times = [times[at] for at in carry]
    carry_sources = [sources[at] for at in carry]
    now = sorted((at for at in range(len(times)) if times[at] < boundary),
                 key=times.__getitem__)
    times, sources = [times[at] for at in now], [sources[at] for at in now]
    parent, depth = [-1] * len(times), [0] * len(times)
    expanded, active = [False] * len(times), [True] * len(times)
    while True:
        index = sorted((at for at in range(len(times)) if active[at] and times[at] < boundary),
                       key=times.__getitem__)
        step_times = [times[at] for at in index]
        located = [_locate(time, windows) for time in step_times]
        spanned = [at for at, (_, in_span, _) in enumerate(located) if in_span]
        avalanche, counted = _avalanches([step_times[at] for at in spanned], last,
                                         effects.dead, effects.paralysable)
        fired = [False] * len(times)
        for at, started in zip(spanned, avalanche):
            if started:
                fired[index[at]] = True
        new = [at for at in range(len(times)) if fired[at] and not expanded[at]]
        if new and effects._after is not None:
            for at in new:
                expanded[at] = True
            for time, source, owner in _children(effects, times, new):
                times.append(time)
                sources.append(source)
                parent.append(owner)
                depth.append(depth[owner] + 1)
                expanded.append(False)
                fired.append(False)
        # A child is there when its parent is and started an avalanche (parents come first)
        present = [True] * len(times)
        for at in range(len(times)):
            if depth[at]:
                present[at] = present[parent[at]] and fired[parent[at]]
        if present == active:
            break
        active = present
    hits = [times[index[at]] for at, started in zip(spanned, avalanche) if started]
    if hits:
        last = max(last, max(hits))
    kept = [False] * len(step_times)
    for at, count in zip(spanned, counted):
        kept[at] = count
    later = [at for at in range(len(times)) if active[at] and times[at] >= boundary]
    carry_times += [times[at] for at in later]
    carry_sources += [sources[at] for at in later]
    return ((step_times, [sources[at] for at in index], located, kept),
            (carry_times, carry_sources), last)


def tdc_few(resolved, starts, keep_last, source_count):
    """The TDC's detections of :func:`resolve_few`'s photons (``starts``: the windows' TDC
    starts, a list) and the photon counters: ``(recorded, counts)``, ``recorded`` a list of
    ``(span, timestamp)``, ``counts`` a list of rows per source (:data:`COUNTERS`)."""
    times, sources, located, counted = resolved
    what = [_OUTSIDE] * len(times)
    fires = []
    for at, ((_, _, in_window), count) in enumerate(zip(located, counted)):
        if in_window:
            what[at] = _OVERWRITTEN if count else _DEAD
            if count:
                fires.append(at)
    recorded = []
    for position, at in enumerate(fires):
        span = located[at][0]
        neighbour = position + 1 if keep_last else position - 1
        if not 0 <= neighbour < len(fires) or located[fires[neighbour]][0] != span:
            what[at] = _RECORDED
            recorded.append((span, min(math.floor(times[at] - starts[span]), TDC_CODES - 1)))
    counts = [[0] * len(COUNTERS) for _ in range(source_count)]
    for source, kind in zip(sources, what):
        counts[source][kind] += 1
        counts[source][_GENERATED] += 1
    return recorded, counts
