"""Bit-exact model of :class:`fliss.hdl.histogram.engine.Histogram`: per-pixel frames.

The model assumes the readout keeps up, as the gateware needs for acquisitions without dead
time: each frame is read out before the next one ends, so frames are back to back.

It models both RAM kinds (``Histogram(ram="dual")`` and ``ram="single"``), with, for single-port
banks, events at least two cycles apart (closer ones are dropped and counted in
``dropped_busy``) and ``enable`` rising no earlier than ``Histogram.init_cycles``.

A frame's counts are an array of shape ``(P, N)``: ``P`` pixels (the addresses ``first_pixel …
first_pixel + P - 1``) of ``N`` bins; the gateware reads them out in flat order
(``counts.ravel()``: index ``pixel * N + bin``).
"""

import numpy as np

from ...hdl.event import ADDRESS_BITS, TIMESTAMP_BITS
from ...hdl.histogram.engine import (BANK_BITS, COUNT_WIDTH, MIN_COUNT_WIDTH, MAX_COUNT_WIDTH,
                                     MAX_SHIFT, MAX_BANK_BITS, INTEGRATION_WIDTH)
from ...hdl.histogram.dual import read_stages
from ...hdl.histogram.readout import readout_cycles_per_bin


__all__ = ["check_settings", "split", "bins_read", "readout_cycles", "histogram", "frames"]


def _integer(value):
    return isinstance(value, (int, np.integer)) and not isinstance(value, bool)


def check_settings(*, shift=0, integration=1, bank_bits=BANK_BITS, count_width=COUNT_WIDTH,
                   pixel_bits=0, first_pixel=0):
    """Raise :exc:`ValueError` unless the histogram settings are valid (the split need not fit
    the bank: the engine then keeps what does, see :func:`split`)."""
    if not _integer(bank_bits) or not 1 <= bank_bits <= MAX_BANK_BITS:
        raise ValueError(f"Bank address width must be an integer from 1 to {MAX_BANK_BITS} "
                         f"bits, not {bank_bits!r}")
    if not _integer(count_width) or not MIN_COUNT_WIDTH <= count_width <= MAX_COUNT_WIDTH:
        raise ValueError(f"Count width must be an integer from {MIN_COUNT_WIDTH} to "
                         f"{MAX_COUNT_WIDTH} bits, not {count_width!r}")
    if not _integer(shift) or not 0 <= shift <= MAX_SHIFT:
        raise ValueError(f"Bin shift must be an integer from 0 to {MAX_SHIFT}, not {shift!r}")
    if not _integer(pixel_bits) or not 0 <= pixel_bits <= ADDRESS_BITS:
        raise ValueError(f"Pixel bits must be an integer from 0 to {ADDRESS_BITS}, "
                         f"not {pixel_bits!r}")
    if not _integer(first_pixel) or not 0 <= first_pixel < (1 << ADDRESS_BITS):
        raise ValueError(f"First pixel must be an address from 0 to {(1 << ADDRESS_BITS) - 1}, "
                         f"not {first_pixel!r}")
    if not _integer(integration) or not 1 <= integration < (1 << INTEGRATION_WIDTH):
        raise ValueError(f"Integration time must be from 1 to {(1 << INTEGRATION_WIDTH) - 1} "
                         f"clock cycles, not {integration!r}")


def split(shift=0, pixel_bits=0, bank_bits=BANK_BITS):
    """``(q, b)``: a frame holds ``2**q`` pixels of ``2**b`` bins. ``q = pixel_bits`` and
    ``b = 13 - shift`` when the split fits the bank (``pixel_bits + 13 - shift <=
    bank_bits``); otherwise ``q = min(pixel_bits, bank_bits)`` and ``b = bank_bits - q``."""
    check_settings(shift=shift, pixel_bits=pixel_bits, bank_bits=bank_bits)
    q = min(pixel_bits, bank_bits)
    return q, min(TIMESTAMP_BITS - shift, bank_bits - q)


def bins_read(shift=0, bank_bits=BANK_BITS, pixel_bits=0):
    """Number of bins read out per frame, all pixels: ``2**(q + b)`` (:func:`split`)."""
    q, b = split(shift, pixel_bits, bank_bits)
    return 1 << (q + b)


def readout_cycles(shift=0, bank_bits=BANK_BITS, pixel_bits=0, ram="dual"):
    """Fewest clock cycles the readout of one frame takes: 4 per bin, 6 with dual-port banks
    of more than one block (their word's way through the read stages)."""
    stages = read_stages(bank_bits) if ram == "dual" else 0
    return readout_cycles_per_bin(stages) * bins_read(shift, bank_bits, pixel_bits)


def histogram(timestamps, addresses=None, *, shift=0, bank_bits=BANK_BITS, pixel_bits=0,
              first_pixel=0, count_width=COUNT_WIDTH):
    """Histograms of one frame, as read out.

    Parameters
    ----------
    timestamps, addresses : array_like
        The frame's events; ``addresses`` None: all of ``first_pixel``.

    Returns
    -------
    counts : numpy.ndarray of int64, shape ``(2**q, 2**b)``
        Saturating counts per pixel and bin (:func:`split`); the readout sends
        ``counts.ravel()``.
    overflow : int
        Events of a pixel of the frame whose bin is beyond ``2**b - 1``.
    dropped_pixel : int
        Events whose address is not a pixel of the frame.
    """
    check_settings(shift=shift, bank_bits=bank_bits, count_width=count_width,
                   pixel_bits=pixel_bits, first_pixel=first_pixel)
    q, b = split(shift, pixel_bits, bank_bits)
    timestamps = np.asarray(timestamps, dtype=np.int64)
    if addresses is None:
        addresses = np.full(len(timestamps), first_pixel, dtype=np.int64)
    addresses = np.asarray(addresses, dtype=np.int64)
    if addresses.shape != timestamps.shape:
        raise ValueError(f"Addresses ({len(addresses)}) and timestamps ({len(timestamps)}) "
                         f"must be as many")
    if np.any((timestamps < 0) | (timestamps >= (1 << TIMESTAMP_BITS))):
        raise ValueError(f"Timestamps must be from 0 to {(1 << TIMESTAMP_BITS) - 1}")
    if np.any((addresses < 0) | (addresses >= (1 << ADDRESS_BITS))):
        raise ValueError(f"Addresses must be from 0 to {(1 << ADDRESS_BITS) - 1}")
    pixels = addresses - first_pixel
    in_window = (pixels >= 0) & (pixels < (1 << q))
    bins = timestamps >> shift
    in_range = in_window & (bins < (1 << b))
    flat = (pixels[in_range] << b) | bins[in_range]
    counts = np.bincount(flat, minlength=1 << (q + b))
    counts = np.minimum(counts, (1 << count_width) - 1).astype(np.int64)
    return (counts.reshape(1 << q, 1 << b), int(np.count_nonzero(in_window & ~in_range)),
            int(np.count_nonzero(~in_window)))


def frames(cycles, timestamps, addresses=None, *, integration, enable, disable=None, shift=0,
           bank_bits=BANK_BITS, pixel_bits=0, first_pixel=0, count_width=COUNT_WIDTH):
    """Frames of an acquisition whose readout keeps up (settings held for all frames).

    Parameters
    ----------
    cycles, timestamps, addresses : array_like
        Arrival cycle, timestamp and address of each event (``addresses`` None: all of
        ``first_pixel``).
    integration : int
        Frame length in clock cycles.
    enable : int
        Cycle in which ``enable`` rises; the first frame starts in the next cycle.
    disable : int or None
        Cycle in which ``enable`` falls; it ends the last frame.

    Returns
    -------
    histograms : list of numpy.ndarray
        One ``(P, N)`` array per frame (:func:`histogram`), in order: every frame that has
        started up to and including cycle ``disable`` (a frame starting in cycle ``disable``
        is empty), or, without ``disable``, up to the last event.
    overflow : int
        Events counted in ``overflow``.
    dropped : int
        Events counted in ``dropped`` (arrived outside every frame).
    dropped_pixel : int
        Events counted in ``dropped_pixel``.
    """
    check_settings(shift=shift, integration=integration, bank_bits=bank_bits,
                   count_width=count_width, pixel_bits=pixel_bits, first_pixel=first_pixel)
    cycles = np.asarray(cycles, dtype=np.int64)
    timestamps = np.asarray(timestamps, dtype=np.int64)
    if addresses is None:
        addresses = np.full(len(timestamps), first_pixel, dtype=np.int64)
    addresses = np.asarray(addresses, dtype=np.int64)
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
    overflow = dropped_pixel = 0
    for k in range(count):
        chosen = inside & (frame == k)
        counts, over, outside = histogram(
            timestamps[chosen], addresses[chosen], shift=shift, bank_bits=bank_bits,
            pixel_bits=pixel_bits, first_pixel=first_pixel, count_width=count_width)
        histograms.append(counts)
        overflow += over
        dropped_pixel += outside
    return histograms, overflow, int(np.count_nonzero(~inside)), dropped_pixel
