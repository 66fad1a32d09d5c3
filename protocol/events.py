"""Events on the link: the numpy form of :class:`fliss.hdl.event.Event` (derived from the gateware
layout) and the payload of an EVENTS packet."""

import numpy as np
from amaranth.lib import data

from ..hdl.event import Event
from ..hdl.protocol import EVENT_BYTES, MAX_EVENTS_PER_PACKET, PacketType
from .frames import encode_frame


__all__ = ["EVENT_DTYPE", "pack", "unpack", "pack_events", "unpack_events", "link_events_per_s"]


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


def pack_events(events):
    """Payload of an EVENTS packet from an ``EVENT_DTYPE`` array."""
    words = pack(events)
    return b"".join(int(word).to_bytes(EVENT_BYTES, "little") for word in words)


def unpack_events(payload):
    """``EVENT_DTYPE`` array from the payload of an EVENTS packet."""
    payload = bytes(payload)
    if len(payload) % EVENT_BYTES:
        raise ValueError(f"Event payload of {len(payload)} bytes is not a whole number of "
                         f"{EVENT_BYTES}-byte events")
    words = np.array([int.from_bytes(payload[i:i + EVENT_BYTES], "little")
                      for i in range(0, len(payload), EVENT_BYTES)], dtype=np.uint64)
    return unpack(words)


def link_events_per_s(baud):
    """Events a second that a link of ``baud`` carries in full EVENTS frames (8N1 characters:
    10 bits a byte), with nothing else on it."""
    payload = bytes(MAX_EVENTS_PER_PACKET * EVENT_BYTES)
    frame_bytes = len(encode_frame(PacketType.EVENTS, 0, payload))
    return baud / 10 / frame_bytes * MAX_EVENTS_PER_PACKET
