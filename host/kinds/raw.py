"""Raw events (capture mode ``"raw"``): EVENTS packets, an array of events each, appended to
``/events`` (which every capture file has) for a duration; exported to PTU and Photon-HDF5."""

import time
from dataclasses import dataclass

import numpy as np
from amaranth.lib import data

from ...hdl.event import Event, TIMESTAMP_BITS
from ...hdl.protocol import EVENT_BYTES
from ...hdl.registers import AcquisitionMode
from ...protocol.events import EVENT_DTYPE
from . import histogram
from .kind import DataKind, Seen


__all__ = ["EventBatch", "unpack_event_payload", "EventAssembler", "KIND"]


@dataclass
class EventBatch:
    """The events of one EVENTS packet (``EVENT_DTYPE``) and the host's receive time."""
    events: np.ndarray
    time_s: float


#: (name, offset, mask) of each Event field, read once from the layout.
_EVENT_FIELDS = [(name, np.uint64(field.offset), np.uint64((1 << field.width) - 1))
                 for name, field in data.Layout.cast(Event)]


def unpack_event_payload(payload: bytes) -> np.ndarray:
    """``EVENT_DTYPE`` array from an EVENTS payload (vectorised; the same result as
    :func:`fliss.protocol.unpack_events`)."""
    if len(payload) % EVENT_BYTES:
        raise ValueError(f"Event payload of {len(payload)} bytes is not a whole number of "
                         f"{EVENT_BYTES}-byte events")
    raw = np.frombuffer(payload, dtype=np.uint8).reshape(-1, EVENT_BYTES)
    padded = np.zeros((len(raw), 8), dtype=np.uint8)
    padded[:, :EVENT_BYTES] = raw
    words = padded.view("<u8")[:, 0]
    events = np.empty(len(words), dtype=EVENT_DTYPE)
    for name, offset, mask in _EVENT_FIELDS:
        events[name] = (words >> offset) & mask
    return events


class EventAssembler:
    """An :class:`EventBatch` of each EVENTS packet; a malformed one is counted and dropped."""

    COUNTERS = ("event_packets", "events")
    FRAMES = None

    def __init__(self, stream):
        self.stream = stream

    def add(self, packet, time_s):
        try:
            events = unpack_event_payload(packet.payload)
        except ValueError:
            self.stream.counters.malformed += 1
            return []
        return self.add_events(events, time_s)

    def add_events(self, events, time_s=None):
        """The events of one EVENTS packet, already unpacked."""
        counters = self.stream.counters
        counters.event_packets += 1
        counters.events += len(events)
        return [EventBatch(events, time.time() if time_s is None else time_s)]

    def flush(self, time_s=None):
        return []


def replay(capture):
    """The events of ``capture`` cut into as many :class:`EventBatch` items as the file
    records batches."""
    batches = max(len(capture.batch_times_s), 1)
    times = capture.batch_times_s if len(capture.batch_times_s) else [0.0]
    for events, time_s in zip(np.array_split(capture.events, batches), times):
        yield EventBatch(events, float(time_s))


def seen(item, shift):
    """An event batch in the live view: its events histogrammed with the view's bin shift and
    summed; not a numbered frame."""
    bins = (1 << TIMESTAMP_BITS) >> shift
    stamps = item.events["timestamp"].astype(np.int64) >> shift
    return Seen(None, True, np.bincount(stamps, minlength=bins)[:bins][np.newaxis],
                len(item.events), False)


def tally(totals, item):
    """A saved batch's events."""
    totals.events += len(item.events)


KIND = DataKind(
    name="raw", rank=3, readout=AcquisitionMode.RAW, packet="events",
    assembler=EventAssembler, item=EventBatch, rows=None, format_version=2,
    what="raw events", counted=True, imager=False,
    # (its events are in /events, which every capture has; /histograms is empty)
    read=histogram.read, tally=tally, replay=replay, seen=seen, exports=("ptu", "photon-hdf5"))
