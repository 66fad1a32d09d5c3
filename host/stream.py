"""Stream assembly: whole histograms from HISTOGRAM chunks, event arrays from EVENTS packets,
depth frames from DEPTH packets.

:class:`StreamAssembler` takes the data packets a board sends, in order of arrival, and returns
:class:`HistogramFrame`, :class:`EventBatch` and :class:`DepthFrame` items; it counts what is
incomplete, lost or malformed (:class:`StreamCounters`).
"""

import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Union

import numpy as np
from amaranth.lib import data

from ..hdl.event import Event, TIMESTAMP_BITS
from ..hdl.histogram import MAX_SHIFT
from ..hdl.protocol import (HISTOGRAM_COUNT_BITS, PacketType, EVENT_BYTES, HistogramChunk,
                            DEPTH_FRACTION_BITS, DEPTH_BACKGROUND_FRACTION_BITS)
from ..sim.codec import Packet, byte_size, unpack_from, word_dtype
from ..sim.depth import unpack_depth
from ..sim.event import EVENT_DTYPE


__all__ = ["HistogramFrame", "EventBatch", "DepthFrame", "StreamCounters", "StreamAssembler",
           "unpack_event_payload", "depth_frame_of"]


_CHUNK_BYTES = byte_size(HistogramChunk)
_COUNT_DTYPE = word_dtype(HISTOGRAM_COUNT_BITS)


@dataclass
class HistogramFrame:
    """One histogram as read out by the board.

    ``counts`` has ``2**13 >> shift`` bins; bins of chunks that never arrived are 0 and
    ``complete`` is False. ``time_s`` is the host's receive time (``time.time()``) of its last
    chunk.
    """
    frame: int
    shift: int
    counts: np.ndarray
    complete: bool
    missing_bins: int
    time_s: float


@dataclass
class EventBatch:
    """The events of one EVENTS packet (``EVENT_DTYPE``) and the host's receive time."""
    events: np.ndarray
    time_s: float


@dataclass
class DepthFrame:
    """One depth frame (a DEPTH packet): per pixel, its strongest peak.

    Pixel ``p`` of the arrays is the sensor's address ``first_pixel + p``. ``position`` is the
    peak's centre in bins of ``2**shift`` timestamp codes from the start of bin 0 (bin ``j``
    spans ``j … j + 1``), NaN where ``detected`` is False; ``height`` the filtered peak above
    background, in counts; ``background`` the mean count per bin outside the peak window.
    ``records`` holds the packet's integers as sent (``position`` in 1/16 bin, also where not
    detected; ``background`` in 1/16 count), ``filter`` and ``threshold`` the settings it was
    made with. ``time_s`` is the host's receive time.
    """
    frame: int
    first_pixel: int
    shift: int
    position: np.ndarray
    height: np.ndarray
    background: np.ndarray
    detected: np.ndarray
    time_s: float
    pixel_bits: int = 0
    filter: int = 0
    threshold: int = 0
    records: Optional[np.ndarray] = None


def depth_frame_of(payload: bytes, time_s: float) -> DepthFrame:
    """The :class:`DepthFrame` of a DEPTH payload; raises :exc:`ValueError` with one line for
    a malformed one."""
    head, records = unpack_depth(payload)
    detected = records["detected"].copy()
    position = records["position"] / (1 << DEPTH_FRACTION_BITS)
    position[~detected] = np.nan
    return DepthFrame(head["frame"], head["first_pixel"], head["shift"], position,
                      records["height"].copy(),
                      records["background"] / (1 << DEPTH_BACKGROUND_FRACTION_BITS), detected,
                      time_s, head["pixel_bits"], head["filter"], head["threshold"], records)


@dataclass
class StreamCounters:
    """What the stream assembler has seen (the link's own counters are the decoder's)."""
    histogram_chunks: int = 0
    frames: int = 0
    incomplete_frames: int = 0
    lost_frames: int = 0
    missing_bins: int = 0
    event_packets: int = 0
    events: int = 0
    malformed: int = 0
    unexpected: int = 0
    depth_frames: int = 0
    lost_depth_frames: int = 0

    def as_dict(self) -> Dict[str, int]:
        return dict(self.__dict__)


#: (name, offset, mask) of each Event field, read once from the layout.
_EVENT_FIELDS = [(name, np.uint64(field.offset), np.uint64((1 << field.width) - 1))
                 for name, field in data.Layout.cast(Event)]


def unpack_event_payload(payload: bytes) -> np.ndarray:
    """``EVENT_DTYPE`` array from an EVENTS payload (vectorised; the same result as
    :func:`fliss.sim.codec.unpack_events`)."""
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


class StreamAssembler:
    """Whole histograms from HISTOGRAM chunks, event arrays from EVENTS packets, depth frames
    from DEPTH packets.

    Feed it data packets in order of arrival with :meth:`add`; it returns what is complete.
    A frame is finished by its ``last`` chunk or by the first chunk of another frame; a frame
    that misses chunks is still returned, with ``complete`` False, and a jump in frame numbers
    counts the frames lost in between. Nothing malformed is accepted: a chunk that does not fit
    its frame is counted in ``malformed`` and dropped, and :attr:`last_malformed` says why.
    A jump in depth frame numbers counts the depth frames lost in ``lost_depth_frames``.
    """

    def __init__(self):
        self.counters = StreamCounters()
        self._frame = None
        self._shift = None
        self._counts = None
        self._filled = None
        self._next_frame = None
        #: One more than the frame number of the last chunk (or DEPTH packet) that ended a
        #: frame: the board's STATUS ``frames`` once every histogram it made has arrived.
        self.frames_ended = None
        #: Why the last malformed packet was dropped (one line), or None.
        self.last_malformed = None
        self._next_depth = None

    def add(self, packet: Packet, time_s: Optional[float] = None
            ) -> List[Union[HistogramFrame, EventBatch]]:
        time_s = time.time() if time_s is None else time_s
        if packet.type == PacketType.HISTOGRAM:
            return self._chunk(packet.payload, time_s)
        if packet.type == PacketType.EVENTS:
            try:
                events = unpack_event_payload(packet.payload)
            except ValueError:
                self.counters.malformed += 1
                return []
            return self.add_events(events, time_s)
        if packet.type == PacketType.DEPTH:
            return self._depth(packet.payload, time_s)
        self.counters.unexpected += 1
        return []

    def add_events(self, events: np.ndarray, time_s: Optional[float] = None
                   ) -> List[EventBatch]:
        """The events of one EVENTS packet, already unpacked (``EVENT_DTYPE``), as by
        :meth:`fliss.host.bulk.BulkDecoder.feed_events`."""
        self.counters.event_packets += 1
        self.counters.events += len(events)
        return [EventBatch(events, time.time() if time_s is None else time_s)]

    def _depth(self, payload, time_s):
        try:
            frame = depth_frame_of(payload, time_s)
        except ValueError as error:
            self.counters.malformed += 1
            self.last_malformed = str(error)
            return []
        if self._next_depth is not None and frame.frame != self._next_depth:
            self.counters.lost_depth_frames += (frame.frame - self._next_depth) % (1 << 32)
        self._next_depth = self.frames_ended = (frame.frame + 1) % (1 << 32)
        self.counters.depth_frames += 1
        return [frame]

    def _chunk(self, payload, time_s):
        out = []
        if len(payload) < _CHUNK_BYTES or (len(payload) - _CHUNK_BYTES) % _COUNT_DTYPE.itemsize:
            self.counters.malformed += 1
            return out
        chunk = unpack_from(HistogramChunk, payload)
        frame, first, shift, last = (chunk["frame"], chunk["first_bin"], chunk["shift"],
                                     chunk["last"])
        counts = np.frombuffer(payload, dtype=_COUNT_DTYPE, offset=_CHUNK_BYTES)
        bins = (1 << TIMESTAMP_BITS) >> shift if shift <= MAX_SHIFT else 0
        if shift > MAX_SHIFT or first + len(counts) > bins or last > 1:
            self.counters.malformed += 1
            return out
        self.counters.histogram_chunks += 1
        if self._frame is not None and (frame != self._frame or shift != self._shift):
            out.append(self._finish(time_s))
        if self._frame is None:
            if self._next_frame is not None and frame != self._next_frame:
                self.counters.lost_frames += (frame - self._next_frame) % (1 << 32)
            self._frame, self._shift = frame, shift
            self._counts = np.zeros(bins, dtype=np.uint32)
            self._filled = np.zeros(bins, dtype=bool)
        self._counts[first:first + len(counts)] = counts
        self._filled[first:first + len(counts)] = True
        if last:
            self.frames_ended = (frame + 1) % (1 << 32)
        if last:
            out.append(self._finish(time_s))
        return out

    def _finish(self, time_s):
        missing = int(np.count_nonzero(~self._filled))
        result = HistogramFrame(self._frame, self._shift, self._counts, missing == 0, missing,
                                time_s)
        self.counters.frames += 1
        if missing:
            self.counters.incomplete_frames += 1
            self.counters.missing_bins += missing
        self._next_frame = (self._frame + 1) % (1 << 32)
        self._frame = self._counts = self._filled = None
        return result

    def flush(self, time_s: Optional[float] = None) -> List[HistogramFrame]:
        """Finish the frame in progress (at the end of a stream); returns it in a list."""
        if self._frame is None:
            return []
        return [self._finish(time.time() if time_s is None else time_s)]
