"""numpy form of :class:`fliss.hdl.event.Event`, derived from the gateware layout."""

import numpy as np
from amaranth.lib import data

from ..hdl.event import Event


__all__ = ["EVENT_DTYPE", "pack", "unpack"]


_LAYOUT = data.Layout.cast(Event)


def _dtype_for(width):
    for dtype in (np.uint8, np.uint16, np.uint32, np.uint64):
        if width <= np.iinfo(dtype).bits:
            return dtype
    raise ValueError(f"no numpy integer holds {width} bits")


#: One field per :class:`Event` field, in layout order, in the smallest unsigned type that fits.
EVENT_DTYPE = np.dtype([(name, _dtype_for(field.width)) for name, field in _LAYOUT])


def pack(events):
    """Events (an ``EVENT_DTYPE`` array) as integers with the gateware's bit layout."""
    words = np.zeros(len(events), dtype=np.uint64)
    for name, field in _LAYOUT:
        values = events[name].astype(np.uint64)
        if np.any(values >> np.uint64(field.width)):
            raise ValueError(f"event field {name!r} does not fit in {field.width} bits")
        words |= values << np.uint64(field.offset)
    return words


def unpack(words):
    """Integers with the gateware's bit layout as an ``EVENT_DTYPE`` array."""
    words = np.asarray(words, dtype=np.uint64)
    events = np.zeros(len(words), dtype=EVENT_DTYPE)
    for name, field in _LAYOUT:
        events[name] = (words >> np.uint64(field.offset)) & np.uint64((1 << field.width) - 1)
    return events
