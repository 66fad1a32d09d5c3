"""The model board's raw events: EVENTS packets of up to MAX_EVENTS_PER_PACKET events, as the
gateware's event packetizer sends them; with ``line_limited``, no more events a block than the
line carries (the rest dropped at the raw FIFO and counted)."""

import numpy as np

from ....hdl.protocol import MAX_EVENTS_PER_PACKET, PacketType
from ....hdl.registers import AcquisitionMode
from ....protocol.events import link_events_per_s, pack_events
from .base import Producer


__all__ = ["PRODUCER"]


class EventProducer(Producer):
    readout = AcquisitionMode.RAW

    def __init__(self):
        self.pending = []

    def reset(self):
        self.pending = []

    def begin(self):
        self.pending = []

    def take(self, board, events):
        if board.line_limited:
            allowed = self._line_events(board, len(events))
            board.status["dropped_fifo"] += len(events) - allowed
            events = events[:allowed]
        self.pending.append(events)

    @staticmethod
    def _line_events(board, count):
        """Events the line carries in one block, in full EVENTS frames (8N1 characters)."""
        seconds = board.settings["integration"] / board.clock_hz
        return min(count, int(seconds * link_events_per_s(board.baud)))

    def send(self, board, final):
        # Whole packets after a block; at a stop, the rest too.
        if not self.pending:
            return
        events = np.concatenate(self.pending)
        whole = len(events) - len(events) % MAX_EVENTS_PER_PACKET
        cut = len(events) if final else whole
        for start in range(0, cut, MAX_EVENTS_PER_PACKET):
            batch = events[start:min(start + MAX_EVENTS_PER_PACKET, cut)]
            board._send(PacketType.EVENTS, pack_events(batch), data=True)
        rest = events[cut:]
        self.pending = [rest] if len(rest) else []


PRODUCER = EventProducer
