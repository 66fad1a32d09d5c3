"""Stream assembly: whole histograms from HISTOGRAM and HISTOGRAM_COMPACT chunks, event arrays
from EVENTS packets, depth frames from DEPTH packets.

:class:`StreamAssembler` takes the data packets a board sends, in order of arrival, and returns
:class:`HistogramFrame`, :class:`EventBatch` and :class:`DepthFrame` items; it counts what is
incomplete, lost or malformed (:class:`StreamCounters`).
"""

import time
from dataclasses import dataclass
from typing import Dict, List, Optional, Union

import numpy as np
from amaranth.lib import data

from ..hdl.event import Event
from ..hdl.protocol import (EVENT_BYTES, DEPTH_FRACTION_BITS,
                            DEPTH_BACKGROUND_FRACTION_BITS)
from ..protocol.frames import Packet
from ..protocol.depth import unpack_depth
from ..protocol.events import EVENT_DTYPE
from ..protocol.histograms import MalformedChunk, decode_chunk
from ..protocol.packets import KIND


__all__ = ["HistogramFrame", "EventBatch", "DepthFrame", "StreamCounters", "StreamAssembler",
           "unpack_event_payload", "depth_frame_of"]


@dataclass
class HistogramFrame:
    """One histogram as read out by the board.

    The frame holds ``P = 2**pixel_bits`` pixels (addresses ``first_pixel …``) of
    ``N = 2**13 >> shift`` bins each; ``counts`` has the ``P * N`` bins, pixel after pixel
    (:attr:`image` is the same as a ``(P, N)`` array). Bins of chunks that never arrived are 0
    and ``complete`` is False. ``time_s`` is the host's receive time (``time.time()``) of its
    last chunk.
    """
    frame: int
    shift: int
    counts: np.ndarray
    complete: bool
    missing_bins: int
    time_s: float
    pixel_bits: int = 0
    first_pixel: int = 0

    @property
    def image(self) -> np.ndarray:
        """``counts`` as ``(pixels, bins)``."""
        return self.counts.reshape(1 << self.pixel_bits, -1)


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


class StreamAssembler:
    """Whole histograms from HISTOGRAM and HISTOGRAM_COMPACT chunks, event arrays from EVENTS
    packets, depth frames from DEPTH packets.

    Feed it data packets in order of arrival with :meth:`add`; it returns what is complete.
    Both forms of a chunk (HISTOGRAM and HISTOGRAM_COMPACT) fill the same frame. A frame is
    finished by its ``last`` chunk or by the first chunk of another frame (or of other
    settings: bin shift, pixel split); a frame
    that misses chunks is still returned, with ``complete`` False, and a jump in frame numbers
    counts the frames lost in between. Nothing malformed is accepted: a chunk that does not fit
    its frame is counted in ``malformed`` and dropped, and :attr:`last_malformed` says why.
    A jump in depth frame numbers counts the depth frames lost in ``lost_depth_frames``.
    """

    def __init__(self):
        self.counters = StreamCounters()
        self._frame = None
        self._settings = None
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
        kind = KIND.get(packet.type)
        if kind == "histogram":
            return self._chunk(packet.type, packet.payload, time_s)
        if kind == "events":
            try:
                events = unpack_event_payload(packet.payload)
            except ValueError:
                self.counters.malformed += 1
                return []
            return self.add_events(events, time_s)
        if kind == "depth":
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

    def _chunk(self, type, payload, time_s):
        out = []
        try:
            chunk = decode_chunk(type, payload)
        except MalformedChunk:
            self.counters.malformed += 1
            return out
        frame, first, counts = chunk.frame, chunk.first_bin, chunk.counts
        settings = (chunk.shift, chunk.pixel_bits, chunk.first_pixel)
        self.counters.histogram_chunks += 1
        if self._frame is not None and (frame != self._frame or settings != self._settings):
            out.append(self._finish(time_s))
        if self._frame is None:
            if self._next_frame is not None and frame != self._next_frame:
                self.counters.lost_frames += (frame - self._next_frame) % (1 << 32)
            self._frame, self._settings = frame, settings
            self._counts = np.zeros(chunk.bins, dtype=np.uint32)
            self._filled = np.zeros(chunk.bins, dtype=bool)
        self._counts[first:first + len(counts)] = counts
        self._filled[first:first + len(counts)] = True
        if chunk.last:
            self.frames_ended = (frame + 1) % (1 << 32)
            out.append(self._finish(time_s))
        return out

    def _finish(self, time_s):
        missing = int(np.count_nonzero(~self._filled))
        shift, pixel_bits, first_pixel = self._settings
        result = HistogramFrame(self._frame, shift, self._counts, missing == 0, missing,
                                time_s, pixel_bits, first_pixel)
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
