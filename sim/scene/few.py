"""The detection of a step with few photons, in plain Python.

In closed loop (the virtual boards) the scene simulator steps one TDC window at a time: a
handful of photons, most often none, where numpy's cost per call (a microsecond or more, some
thirty calls a step) outweighs the work. :func:`detect` does what the vectorised code of
:meth:`~fliss.sim.scene.photons.Simulation.step` does after the photons are drawn (spans, the
non-paralysable SPAD, the single-hit TDC, the counters) with the same float64 arithmetic on
Python floats, so it gives the same events and counters, bit for bit; :func:`detect_pixels`
does the same for a pixel array (:meth:`~fliss.sim.scene.array.PixelSimulation.step`, both
sensors). ``tests/models/test_scene.py`` runs both paths on the same draws.
"""

from bisect import bisect_right
import math

from .description import COUNTERS, TDC_CODES


__all__ = ["FEW_PHOTONS", "detect", "detect_pixels", "timestamp"]


#: Largest number of photons a step resolves in plain Python (beyond, numpy is as cheap).
FEW_PHOTONS = 40

_GENERATED, _OUTSIDE, _DEAD, _OVERWRITTEN, _RECORDED = range(len(COUNTERS))


def detect(times, sources, windows, dead, last_detection, keep_last, source_count):
    """Which of the photons ``times`` (Python floats, in time order; ``sources`` their source
    indices) the SPAD detects and the TDC records, as
    :meth:`~fliss.sim.scene.photons.Simulation.step` does.

    ``windows`` is ``(starts, span_starts, ends, separated)`` as Python lists (``span_starts``
    and ``ends`` ``None`` when ``separated``), ``dead`` the dead time and ``last_detection`` the
    time of the last detection before them, in LSBs; ``keep_last``: the TDC keeps the last
    photon of a window (else the first). Returns ``(recorded, counts, last_detection)``:
    ``(span, time)`` of each photon recorded, in time order, the ``(source_count,
    len(COUNTERS))`` counters as nested lists, and the time of the last detection."""
    counts = [[0] * len(COUNTERS) for _ in range(source_count)]
    fires = []                      # (span, time, source) of detections in a window
    reference = last_detection
    for time, source in zip(times, sources):
        row = counts[source]
        row[_GENERATED] += 1
        # Which span the photon is in: the TDC window of `span`, or the dead time before it
        span, in_span, in_window = _locate(time, windows, dead)
        if not in_window:
            row[_OUTSIDE] += 1
        if not in_span:
            continue
        # The non-paralysable SPAD: blind for `dead` after each detection
        if dead > 0 and time - reference < dead:
            if in_window:
                row[_DEAD] += 1
            continue
        reference = time
        if in_window:
            fires.append((span, time, source))
    # The single-hit TDC: one detection per window, the last (first) one
    recorded = []
    for index, (span, time, source) in enumerate(fires):
        if keep_last:
            kept = index + 1 == len(fires) or fires[index + 1][0] != span
        else:
            kept = index == 0 or fires[index - 1][0] != span
        if kept:
            recorded.append((span, time))
            counts[source][_RECORDED] += 1
        else:
            counts[source][_OVERWRITTEN] += 1
    return recorded, counts, reference


def timestamp(time, start):
    """The TDC code of a photon at ``time`` in the window from ``start`` (LSBs)."""
    return min(math.floor(time - start), TDC_CODES - 1)


def detect_pixels(times, pixels, windows, dead, last_detections, options):
    """:func:`detect` for a pixel array, as
    :meth:`~fliss.sim.scene.array.PixelSimulation.step` does: ``pixels`` gives each photon's
    pixel, ``last_detections`` (a list, updated) each pixel's last detection, ``options`` is
    ``(keep_last, column, collision window in LSBs)``. Returns ``(recorded, what)``:
    ``(span, time, pixel, collision flag)`` of each event, in the sensor's order, and what
    became of each photon (the index of its counter)."""
    keep_last, column, collision = options
    what = [_OUTSIDE] * len(times)
    located = [_locate(time, windows, dead) for time in times]
    spanned = [index for index, (_, in_span, _) in enumerate(located) if in_span]
    # Each pixel's SPAD, as PixelSimulation._detect lays the pixels' photons on one axis
    # (blocks `stride` apart, each from the pixel's last detection): the same arithmetic.
    detected = {}
    if spanned and dead > 0:
        origin = times[spanned[0]]
        stride = (times[spanned[-1]] - origin) + 4.0 * dead + 1.0
        references = {}
        for index in spanned:
            pixel = pixels[index]
            if pixel not in references:
                references[pixel] = max(last_detections[pixel] - origin, -2.0 * dead) \
                    + pixel * stride
            keyed = (times[index] - origin) + pixel * stride
            if keyed - references[pixel] >= dead:
                references[pixel] = keyed
                detected[index] = True
    else:
        detected = dict.fromkeys(spanned, True)
    for index in detected:
        pixel = pixels[index]
        last_detections[pixel] = max(last_detections[pixel], times[index])
    fires = []
    for index in spanned:
        if located[index][2]:
            if index in detected:
                fires.append(index)
                what[index] = _OVERWRITTEN
            else:
                what[index] = _DEAD
    if column:
        recorded = _column(fires, times, pixels, located, keep_last, collision)
    else:
        # One TDC per pixel: per (window, pixel) the last (first) detection, in address order
        groups = {}
        for index in fires:
            key = (located[index][0], pixels[index])
            if keep_last or key not in groups:
                groups[key] = index
        recorded = [(key[0], times[index], key[1], 0, index)
                    for key, index in sorted(groups.items())]
    for *_, index in recorded:
        what[index] = _RECORDED
    return [event[:4] for event in recorded], what


def _locate(time, windows, dead):
    """``(span, in_span, in_window)`` of a photon at ``time`` (see ``spans``)."""
    starts, span_starts, ends, separated = windows
    if separated:
        span = bisect_right(starts, time + dead) - 1
        offset = time - starts[max(span, 0)]
        in_span = span >= 0 and offset < TDC_CODES
        return span, in_span, in_span and offset >= 0
    span = bisect_right(span_starts, time) - 1
    clipped = max(span, 0)
    in_span = span >= 0 and time < ends[clipped]
    return span, in_span, in_span and time >= starts[clipped]


def _column(fires, times, pixels, located, keep_last, collision):
    """The column's TDC: per window the last (first) detection of any pixel, with the
    collision flag (another pixel's detection in the same window less than ``collision``
    before (after) it)."""
    recorded = []
    count = len(fires)
    for position, index in enumerate(fires):
        span = located[index][0]
        neighbour = position + (1 if keep_last else -1)
        if 0 <= neighbour < count and located[fires[neighbour]][0] == span:
            continue                            # not the last (first) of its window
        step = -1 if keep_last else 1
        other = position + step
        while 0 <= other < count and pixels[fires[other]] == pixels[index]:
            other += step
        near = 0
        if 0 <= other < count:
            neighbour = fires[other]
            near = int(located[neighbour][0] == span
                       and abs(times[index] - times[neighbour]) < collision)
        recorded.append((span, times[index], pixels[index], near, index))
    return recorded
