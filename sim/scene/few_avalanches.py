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
from .few import _column as few_column


__all__ = ["resolve_few", "tdc_few", "counters"]


_GENERATED, _OUTSIDE, _DEAD, _OVERWRITTEN, _RECORDED = range(len(COUNTERS))


def _tail(effects, times, sources, first):
    """:meth:`~fliss.sim.scene.avalanches.Avalanches.tail` on lists (``times`` changed in place)."""
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


def _children(effects, times, pixels, parents):
    """The afterpulses and crosstalk of the avalanches ``parents`` (indices), as
    :meth:`~fliss.sim.scene.avalanches.Avalanches._children`: ``(time, source, pixel, parent)`` of each."""
    children = []
    if effects._after is not None:
        probability, cumulative, means, source = effects._after
        draws = effects._after_draws.list(3 * len(parents))
        has = [at for at in range(len(parents)) if draws[3 * at] < probability]
        if has:
            cumulative, means = cumulative.tolist(), means.tolist()
            logs = np.log1p(-np.array([draws[3 * at + 2] for at in has])).tolist()
            for at, log in zip(has, logs):
                kind = min(bisect_right(cumulative, draws[3 * at + 1]), len(means) - 1)
                owner = parents[at]
                children.append((times[owner] - means[kind] * log, source, pixels[owner],
                                 owner))
    if effects._cross is not None:
        targets, chance, source = _cross_lists(effects)
        draws = effects._cross_draws.list(8 * len(parents))
        hits = [(owner, column) for at, owner in enumerate(parents)
                for column, odds in chance[pixels[owner]]
                if draws[8 * at + column] < odds]
        delays = effects._cross_delays.list(len(hits))
        sigma = effects._sigma
        for (owner, column), normal in zip(hits, delays):
            children.append((times[owner] + sigma * abs(normal), source,
                             targets[pixels[owner]][column], owner))
    return children


def _cross_lists(effects):
    """The crosstalk's targets of ``effects`` and each pixel's ``(column, chance)`` of its
    neighbours with a chance above 0 (a uniform draw is never below 0), as lists (made once)."""
    lists = getattr(effects, "_few_cross", None)
    if lists is None:
        targets, chance, source = effects._cross
        chances = [[(column, odds) for column, odds in enumerate(row) if odds > 0]
                   for row in chance.tolist()]
        lists = effects._few_cross = (targets.tolist(), chances, source)
    return lists


def _avalanches(times, pixels, last, dead, paralysable):
    """:func:`~fliss.sim.scene.avalanches.pixel_avalanches` on lists (``last``: each pixel's
    last avalanche): for each photon, whether it starts an avalanche and whether it counts."""
    count = len(times)
    if count == 0 or dead <= 0:
        return [True] * count, [True] * count
    if paralysable:
        counted, previous = [], {}
        for time, pixel in zip(times, pixels):
            counted.append(time - previous.get(pixel, last[pixel]) >= dead)
            previous[pixel] = time
        return [True] * count, counted
    # pixel_avalanches' one axis: each pixel's block from its last avalanche, the blocks more
    # than a dead time apart, so each pixel on its own (the same keys, the same arithmetic)
    origin = times[0]
    stride = (times[-1] - origin) + 4.0 * dead + 1.0
    references, counted = {}, []
    for time, pixel in zip(times, pixels):
        if pixel not in references:
            references[pixel] = max(last[pixel] - origin, -2.0 * dead) + pixel * stride
        key = (time - origin) + pixel * stride
        counted.append(key - references[pixel] >= dead)
        if counted[-1]:
            references[pixel] = key
    return counted, counted


def _locate(time, windows):
    """``(span, in_span, in_window)`` of one photon, as :func:`~fliss.sim.scene.detection.spans`
    with spans that touch (``windows``: ``(starts, span_starts, ends)``, lists)."""
    starts, span_starts, ends = windows
    span = bisect_right(span_starts, time) - 1
    clipped = max(span, 0)
    in_span = span >= 0 and time < ends[clipped]
    return span, in_span, in_span and time >= starts[clipped]


def resolve_few(effects, photons, carried, windows, last, boundary):
    """A step's photons through the detector's effects (``effects``: the step's
    :class:`~fliss.sim.scene.avalanches.Avalanches`): ``photons`` ``(times, sources, pixels)``
    (lists, not sorted; the first ``carried`` carried over), ``windows`` as :func:`_locate`
    takes them, ``last`` each pixel's last avalanche (a list, updated). Returns the photons
    before ``boundary`` with their children in time order, ``(times, sources, pixels, located,
    counted)`` (``located``: each one's ``(span, in_span, in_window)``), and the photons and
    children carried over, ``(times, sources, pixels)``."""
    times, sources, pixels = (list(values) for values in photons)
    _tail(effects, times, sources, carried)
    carry = [at for at in range(len(times)) if times[at] >= boundary]
    carried_over = [[values[at] for at in carry] for values in (times, sources, pixels)]
    now = sorted((at for at in range(len(times)) if times[at] < boundary),
                 key=times.__getitem__)
    times, sources, pixels = ([values[at] for at in now] for values in (times, sources, pixels))
    parent, depth = [-1] * len(times), [0] * len(times)
    expanded, active = [False] * len(times), [True] * len(times)
    initial = list(last)
    while True:
        index = sorted((at for at in range(len(times)) if active[at] and times[at] < boundary),
                       key=times.__getitem__)
        located = [_locate(times[at], windows) for at in index]
        spanned = [at for at, (_, in_span, _) in enumerate(located) if in_span]
        avalanche, counted = _avalanches([times[index[at]] for at in spanned],
                                         [pixels[index[at]] for at in spanned], initial,
                                         effects.dead, effects.paralysable)
        fired = [False] * len(times)
        for at, started in zip(spanned, avalanche):
            if started:
                fired[index[at]] = True
        new = [at for at in range(len(times)) if fired[at] and not expanded[at]]
        if new and (effects._after is not None or effects._cross is not None):
            for at in new:
                expanded[at] = True
            for time, source, pixel, owner in _children(effects, times, pixels, new):
                times.append(time)
                sources.append(source)
                pixels.append(pixel)
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
    for at, started in zip(spanned, avalanche):
        if started:
            pixel = pixels[index[at]]
            last[pixel] = max(last[pixel], times[index[at]])
    kept = [False] * len(index)
    for at, count in zip(spanned, counted):
        kept[at] = count
    later = [at for at in range(len(times)) if active[at] and times[at] >= boundary]
    for values, more in zip(carried_over, (times, sources, pixels)):
        values += [more[at] for at in later]
    return ([[values[at] for at in index] for values in (times, sources, pixels)]
            + [located, kept], carried_over)


def tdc_few(resolved, starts, options, source_count):
    """The TDC's detections of :func:`resolve_few`'s photons (``starts``: the windows' TDC
    starts, a list; ``options``: ``(keep_last, column, collision window in LSBs)``; one pixel
    is a column) and what became of each photon: ``(recorded, what)``, ``recorded`` a
    list of ``(span, timestamp, pixel, collision flag)`` in the sensor's order."""
    keep_last, column, collision = options
    times, sources, pixels, located, counted = resolved
    what = [_OUTSIDE] * len(times)
    fires = []
    for at, ((_, _, in_window), count) in enumerate(zip(located, counted)):
        if in_window:
            what[at] = _OVERWRITTEN if count else _DEAD
            if count:
                fires.append(at)
    if not column:
        # One TDC per pixel: per (window, pixel) the last (first) detection, in address order
        groups = {}
        for at in fires:
            key = (located[at][0], pixels[at])
            if keep_last or key not in groups:
                groups[key] = at
        recorded = [(key[0], times[at], key[1], 0, at) for key, at in sorted(groups.items())]
    else:
        recorded = few_column(fires, times, pixels, located, keep_last, collision)
    for *_, at in recorded:
        what[at] = _RECORDED
    return [(span, min(math.floor(time - starts[span]), TDC_CODES - 1), pixel, near)
            for span, time, pixel, near, _ in recorded], what


def counters(sources, what, source_count):
    """The photon counters of one pixel (rows per source, :data:`COUNTERS`)."""
    counts = [[0] * len(COUNTERS) for _ in range(source_count)]
    for source, kind in zip(sources, what):
        counts[source][kind] += 1
        counts[source][_GENERATED] += 1
    return counts
