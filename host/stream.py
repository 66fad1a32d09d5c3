"""Stream assembly: the data packets a board sends, in order of arrival, assembled into the items
of their kind of data (:mod:`fliss.host.kinds`): whole histograms from HISTOGRAM and
HISTOGRAM_COMPACT chunks (:class:`HistogramFrame`), event arrays from EVENTS packets
(:class:`EventBatch`), depth frames from DEPTH packets (:class:`DepthFrame`).

:class:`StreamAssembler` hands each packet to its kind's assembler and counts what is
incomplete, lost or malformed (:class:`StreamCounters`).
"""

import time
from dataclasses import dataclass
from typing import Dict, List, Optional

import numpy as np

from ..hdl.protocol import PacketType
from ..protocol.frames import Packet
from ..protocol.packets import KIND
from .kinds import KINDS, assemblers
from .kinds.depth import DepthFrame, depth_frame_of
from .kinds.histogram import HistogramFrame
from .kinds.raw import EventBatch, unpack_event_payload


__all__ = ["HistogramFrame", "EventBatch", "DepthFrame", "StreamCounters", "StreamAssembler",
           "unpack_event_payload", "depth_frame_of"]


@dataclass
class StreamCounters:
    """What the stream assembler has seen (the link's own counters are the decoder's): these,
    and any more that a kind's assembler declares (its ``COUNTERS``), from 0."""
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
    #: Data items the link's queue had no room for (:mod:`fliss.host.link`), and the most
    #: bytes it held.
    queue_dropped_frames: int = 0
    queue_dropped_events: int = 0
    queue_peak_bytes: int = 0

    def __post_init__(self):
        for assembler in dict.fromkeys(kind.assembler for kind in KINDS.values()):
            for name in assembler.COUNTERS:
                if not hasattr(self, name):
                    setattr(self, name, 0)

    def as_dict(self) -> Dict[str, int]:
        return dict(self.__dict__)


class StreamAssembler:
    """The items of each kind of data from its packets.

    Feed it data packets in order of arrival with :meth:`add`; it returns what is complete,
    as its kind's assembler (:attr:`fliss.host.kinds.DataKind.assembler`) makes it: both forms
    of a histogram chunk fill the same frame; a frame is finished by its ``last`` chunk or by
    the first chunk of another frame (or of other settings: bin shift, pixel split); a frame
    that misses chunks is still returned, with ``complete`` False, and a jump in frame numbers
    counts the frames lost in between. Nothing malformed is accepted: a packet that does not
    fit is counted in ``malformed`` and dropped, and :attr:`last_malformed` says why where
    its kind tells. A jump in depth frame numbers counts the depth frames lost in
    ``lost_depth_frames``. A packet of no kind is counted in ``unexpected``.
    """

    def __init__(self):
        self.counters = StreamCounters()
        #: One more than the frame number of the last chunk (or DEPTH packet) that ended a
        #: frame: the board's STATUS ``frames`` once every histogram it made has arrived.
        self.frames_ended = None
        #: Why the last malformed packet was dropped (one line), or None.
        self.last_malformed = None
        self._assemblers = assemblers(self)

    @property
    def frames_arrived(self) -> int:
        """The frames of every kind assembled so far (histograms and depth frames, which the
        board numbers apart, as its STATUS ``frames`` counts them together)."""
        return sum(getattr(self.counters, assembler.FRAMES)
                   for assembler in self._assemblers.values() if assembler.FRAMES)

    def add(self, packet: Packet, time_s: Optional[float] = None) -> list:
        time_s = time.time() if time_s is None else time_s
        assembler = self._assemblers.get(KIND.get(packet.type))
        if assembler is None:
            self.counters.unexpected += 1
            return []
        return assembler.add(packet, time_s)

    def add_events(self, events: np.ndarray, time_s: Optional[float] = None
                   ) -> List[EventBatch]:
        """The events of one EVENTS packet, already unpacked (``EVENT_DTYPE``), as by
        :meth:`fliss.host.bulk.BulkDecoder.feed_events`."""
        return self._assemblers[KIND[PacketType.EVENTS]].add_events(events, time_s)

    def flush(self, time_s: Optional[float] = None) -> list:
        """Finish the frame in progress (at the end of a stream); returns it in a list."""
        time_s = time.time() if time_s is None else time_s
        return [item for assembler in self._assemblers.values()
                for item in assembler.flush(time_s)]
