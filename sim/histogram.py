"""Bit-exact model of :class:`fliss.hdl.histogram.Histogram`.

The model assumes the readout keeps up, as the gateware needs for acquisitions without dead
time: each frame is read out before the next one ends, so frames are back to back.

It models both RAM kinds (``Histogram(ram="dual")`` and ``ram="single"``), with, for single-port
banks, events at least two cycles apart (closer ones are dropped and counted in
``dropped_busy``) and ``enable`` rising no earlier than ``Histogram.init_cycles``.
"""

import numpy as np

from ..hdl.event import TIMESTAMP_BITS
from ..hdl.histogram import (BIN_BITS, COUNT_WIDTH, MIN_COUNT_WIDTH, MAX_COUNT_WIDTH, MAX_SHIFT,
                             INTEGRATION_WIDTH, READOUT_CYCLES_PER_BIN)


__all__ = ["check_settings", "bins_read", "readout_cycles", "histogram", "frames"]


def check_settings(*, shift=0, integration=1, bin_bits=BIN_BITS, count_width=COUNT_WIDTH):
    """Raise :exc:`ValueError` unless the histogram settings are valid."""
    if not isinstance(bin_bits, (int, np.integer)) or not 1 <= bin_bits <= TIMESTAMP_BITS:
        raise ValueError(f"Bin index width must be an integer from 1 to {TIMESTAMP_BITS} "
                         f"bits, not {bin_bits!r}")
    if not isinstance(count_width, (int, np.integer)) or \
            not MIN_COUNT_WIDTH <= count_width <= MAX_COUNT_WIDTH:
        raise ValueError(f"Count width must be an integer from {MIN_COUNT_WIDTH} to "
                         f"{MAX_COUNT_WIDTH} bits, not {count_width!r}")
    if not isinstance(shift, (int, np.integer)) or not 0 <= shift <= MAX_SHIFT:
        raise ValueError(f"Bin shift must be an integer from 0 to {MAX_SHIFT}, not {shift!r}")
    if not isinstance(integration, (int, np.integer)) or \
            not 1 <= integration < (1 << INTEGRATION_WIDTH):
        raise ValueError(f"Integration time must be from 1 to {(1 << INTEGRATION_WIDTH) - 1} "
                         f"clock cycles, not {integration!r}")


def bins_read(shift=0, bin_bits=BIN_BITS):
    """Number of bins read out per frame: ``2**min(bin_bits, 13 - shift)``."""
    check_settings(shift=shift, bin_bits=bin_bits)
    return 1 << min(bin_bits, TIMESTAMP_BITS - shift)


def readout_cycles(shift=0, bin_bits=BIN_BITS):
    """Fewest clock cycles the readout of one frame takes."""
    return READOUT_CYCLES_PER_BIN * bins_read(shift, bin_bits)


def histogram(timestamps, *, shift=0, bin_bits=BIN_BITS, count_width=COUNT_WIDTH):
    """Histogram of one frame, as read out.

    Returns
    -------
    counts : numpy.ndarray of int64
        ``bins_read(shift, bin_bits)`` saturating counts.
    overflow : int
        Events whose bin is beyond ``2**bin_bits - 1``.
    """
    check_settings(shift=shift, bin_bits=bin_bits, count_width=count_width)
    timestamps = np.asarray(timestamps, dtype=np.int64)
    if np.any((timestamps < 0) | (timestamps >= (1 << TIMESTAMP_BITS))):
        raise ValueError(f"Timestamps must be from 0 to {(1 << TIMESTAMP_BITS) - 1}")
    bins = timestamps >> shift
    in_range = bins < (1 << bin_bits)
    counts = np.bincount(bins[in_range], minlength=bins_read(shift, bin_bits))
    counts = np.minimum(counts, (1 << count_width) - 1).astype(np.int64)
    return counts, int(np.count_nonzero(~in_range))


def frames(cycles, timestamps, *, integration, enable, disable=None, shift=0,
           bin_bits=BIN_BITS, count_width=COUNT_WIDTH):
    """Frames of an acquisition whose readout keeps up.

    Parameters
    ----------
    cycles, timestamps : array_like
        Arrival cycle and timestamp of each event.
    integration : int
        Frame length in clock cycles.
    enable : int
        Cycle in which ``enable`` rises; the first frame starts in the next cycle.
    disable : int or None
        Cycle in which ``enable`` falls; it ends the last frame.

    Returns
    -------
    histograms : list of numpy.ndarray
        One histogram per frame, in order: every frame that has started up to and including
        cycle ``disable`` (a frame starting in cycle ``disable`` is empty), or, without
        ``disable``, up to the last event.
    overflow : int
        Events counted in ``overflow``.
    dropped : int
        Events counted in ``dropped`` (arrived outside every frame).
    """
    check_settings(shift=shift, integration=integration, bin_bits=bin_bits,
                   count_width=count_width)
    cycles = np.asarray(cycles, dtype=np.int64)
    timestamps = np.asarray(timestamps, dtype=np.int64)
    start = enable + 1
    inside = cycles >= start
    if disable is not None:
        inside &= cycles < disable
    frame = (cycles - start) // integration
    if disable is not None:
        # a frame that starts in the cycle `enable` falls ends at once and is read out empty
        count = (disable - start) // integration + 1 if disable >= start else 0
    else:
        count = int(frame[inside].max()) + 1 if np.any(inside) else 0
    histograms = []
    overflow = 0
    for k in range(count):
        counts, over = histogram(timestamps[inside & (frame == k)], shift=shift,
                                 bin_bits=bin_bits, count_width=count_width)
        histograms.append(counts)
        overflow += over
    return histograms, overflow, int(np.count_nonzero(~inside))
