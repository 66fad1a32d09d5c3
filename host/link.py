"""The link to a FLISS board: frames in and out of a serial port, replies matched to the
commands that wait for them, data packets assembled.

:class:`BoardLink` opens a port with :func:`serial.serial_for_url`, so a device path
(``/dev/ttyUSB1``), a pty of a virtual board (``/dev/pts/7``), ``loop://`` and
``socket://host:port`` all work the same. Every byte received goes through one
:class:`fliss.protocol.FrameDecoder`, which checks CRC and sequence numbers and counts what
is lost or damaged (a :class:`fliss.host.bulk.BulkDecoder`, which decodes large reads with numpy
and gives the same results); replies go to the command that waits for them, data packets to a
:class:`~fliss.host.stream.StreamAssembler`, which turns HISTOGRAM chunks into whole histograms
and EVENTS packets into event arrays.

Commands are sent with a sequence number and re-sent with the *same* one when no reply comes in
time (``timeout_s``, ``retries``; by default :data:`~fliss.host.port.DEFAULT_TIMEOUT_S`, or
:data:`~fliss.host.port.PTY_TIMEOUT_S` on a pseudo-terminal, such as a virtual board's). A reply
is matched by what it answers: an ACK or NAK by the sequence number in its payload, other replies
by what the command expects (:meth:`BoardLink.command`). The commands themselves are
:class:`fliss.host.client.BoardClient`'s.

The data received and not yet taken wait in a queue of at most :attr:`BoardLink.queue_limit`
bytes (of the items' arrays). The link reads only when asked to (a command waiting for its
reply, or :meth:`~fliss.host.client.BoardClient.stream` with its queue empty), so a reader
that takes its data slower than the board sends leaves them in the port's buffer, where a
real UART's driver drops what does not fit and the decoder counts the gap; a command that
must read through more data than the queue takes to find its reply drops the data items
beyond it, counted in the stream's ``queue_dropped_frames`` and ``queue_dropped_events``.
"""

import logging
import termios
import time
from collections import deque
from typing import Callable, Dict, List, Optional, Union

import serial

from ..hdl.protocol import (CONSISTENCY, DEFAULT_BAUD, DELIMITER, LINK_ERRORS, Nak, NakCode,
                            PacketType)
from ..hdl.registers import BY_ADDRESS
from ..protocol.frames import LinkCounters, Packet, PacketEncoder
from ..protocol.layout import byte_size, unpack
from ..protocol.packets import DATA_TYPES
from .bulk import BulkDecoder
from .errors import BoardLost, BoardRefused
from .port import default_timeout, open_port
from .stream import EventBatch, HistogramFrame, StreamAssembler, StreamCounters


__all__ = ["BoardLink"]


_logger = logging.getLogger(__name__)

_LINK_CODES = {code.value for code in LINK_ERRORS}

#: Most bytes (of the items' arrays) the queue of data received and not yet taken holds.
QUEUE_LIMIT = 16 << 20


def _nbytes(item):
    """Bytes of an item's arrays (a histogram's counts, a batch's events, a depth frame's)."""
    return sum(value.nbytes for value in vars(item).values() if hasattr(value, "nbytes"))


class BoardLink:
    """The link to a FLISS board on a serial port.

    Parameters
    ----------
    port : str
        Device path, pty path or pyserial URL (``loop://``, ``socket://host:port``).
    baud : int
        Baud rate of the port (ignored by ptys and sockets).
    timeout_s : float or None
        How long to wait for each reply; ``None``: :func:`default_timeout` of ``port``.
    retries : int
        How often to re-send a command that got no reply.
    serial_port : serial.SerialBase or None
        An open port to use instead of opening ``port``.
    queue_limit : int
        Most bytes of data items (their arrays) queued and not yet taken.
    """

    def __init__(self, port: str, *, baud: int = DEFAULT_BAUD, timeout_s: Optional[float] = None,
                 retries: int = 3, serial_port: Optional[serial.SerialBase] = None,
                 queue_limit: int = QUEUE_LIMIT) -> None:
        self.port_name = port
        self.timeout_s = float(default_timeout(port) if timeout_s is None else timeout_s)
        self.retries = int(retries)
        self.serial = open_port(port, baud) if serial_port is None else serial_port
        self.decoder = BulkDecoder(synced=False)
        self.encoder = PacketEncoder()
        self.assembler = StreamAssembler()
        self._answered = False      # any reply yet (a silent board is reported once)
        self.retransmissions = 0
        self.link_naks = 0
        self.stale_replies = 0
        #: The last reply :meth:`command` returned (other than an ACK).
        self.last_reply = None
        self._replies = deque()
        self._data = deque()
        self.queue_limit = int(queue_limit)
        self._queued = 0            # bytes of the items in _data
        self._last_rx = self._last_data = time.monotonic()
        self._baseline = {}
        try:
            try:
                self.serial.reset_input_buffer()
            except (serial.SerialException, OSError, termios.error) as error:
                self._lost(error)
            self._sync()
        except BaseException:
            self.close()
            raise

    def _sync(self):
        """Get the decoder in step with the board's frames.

        A lone delimiter flushes any half-received frame out of the board's decoder, and a PING
        makes the board send a frame whose delimiter synchronises ours (the first frame is
        skipped as a resynchronisation: the decoder cannot know where it began). A board that
        does not answer is found out by the next command.
        """
        self._send(bytes([DELIMITER]) + self.encoder.frame(PacketType.PING))
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline:
            self.poll(0.02)
            if self.decoder.counters.resyncs or self.decoder.counters.packets:
                self._answered = True
                break
        else:
            self._not_answering("PING")
        self._replies.clear()
        self.reset_counters()

    def _not_answering(self, what):   # said once, at the first timeout, not minutes later
        if not self._answered:
            self._answered = True
            _logger.warning("the board on %s is not answering yet (no reply to %s in %g s); "
                            "still trying", self.port_name, what, self.timeout_s)

    def reset_counters(self) -> None:
        """Count link and stream events from now on (the decoder keeps its totals)."""
        self._baseline = self._raw_link_counters()
        self.assembler.counters = StreamCounters()

    # Context manager

    def close(self) -> None:
        try:
            self.serial.close()
        except Exception:   # closing a port that is already gone
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # Receiving

    def _lost(self, error):
        raise BoardLost(f"lost the connection to the board on {self.port_name} "
                        f"({str(error) or type(error).__name__})") from None

    def poll(self, wait_s: float = 0.05) -> int:
        """Read what has arrived (waiting up to ``wait_s`` for the first byte) and decode it.
        Returns the number of bytes read.

        The event batches of one read are queued after its other data (in a read of
        :data:`~fliss.host.bulk.BULK_MIN_BYTES` or more, which is decoded in bulk)."""
        try:
            waiting = self.serial.in_waiting
            if not waiting:
                self.serial.timeout = wait_s
            data = self.serial.read(max(waiting, 1))
            if data and self.serial.in_waiting:
                data += self.serial.read(self.serial.in_waiting)
        except (serial.SerialException, OSError, termios.error) as error:
            self._lost(error)
        if data:
            self._last_rx = time.monotonic()
            now = time.time()
            decoded = self.decoder.feed_events(data)
            for item in decoded.items:
                if isinstance(item, Packet):
                    if item.type in DATA_TYPES:
                        self._last_data = self._last_rx
                        self._queue(self.assembler.add(item, now))
                    else:
                        self._replies.append(item)
            for events in decoded.batches():
                self._last_data = self._last_rx
                self._queue(self.assembler.add_events(events, now))
        return len(data)

    def _queue(self, items):
        # Data items into the queue, up to its limit; those beyond it dropped and counted
        counters = self.assembler.counters
        for item in items:
            size = _nbytes(item)
            if self._queued + size > self.queue_limit and self._data:
                if isinstance(item, EventBatch):
                    counters.queue_dropped_events += len(item.events)
                else:
                    counters.queue_dropped_frames += 1
                continue
            self._data.append(item)
            self._queued += size
            counters.queue_peak_bytes = max(counters.queue_peak_bytes, self._queued)

    @property
    def queued(self) -> int:
        """Data items received and not yet taken."""
        return len(self._data)

    def next_data(self):
        """The oldest data item received and not yet taken (None if none)."""
        if not self._data:
            return None
        item = self._data.popleft()
        self._queued -= _nbytes(item)
        return item

    @property
    def idle_s(self) -> float:
        """Seconds since the last byte arrived."""
        return time.monotonic() - self._last_rx

    @property
    def link(self) -> LinkCounters:
        """The decoder's :class:`~fliss.protocol.LinkCounters`."""
        return self.decoder.counters

    def link_counters(self) -> Dict[str, int]:
        """Link counters since :meth:`reset_counters` as a flat dict, with the client's own
        retry counters."""
        raw = self._raw_link_counters()
        return {name: value - self._baseline.get(name, 0) for name, value in raw.items()}

    def _raw_link_counters(self):
        c = self.decoder.counters
        out = {"bytes": c.bytes, "packets": c.packets, "payload_bytes": c.payload_bytes,
               "sequence_gaps": c.sequence_gaps, "missing_packets": c.missing_packets,
               "resyncs": c.resyncs, "skipped_bytes": c.skipped_bytes,
               "dropped_frames": c.dropped_frames}
        for code, count in c.errors.items():
            out[code.name.lower()] = count
        out.update(retransmissions=self.retransmissions, link_naks=self.link_naks,
                   stale_replies=self.stale_replies)
        return out

    def take_data(self) -> List[Union[HistogramFrame, EventBatch]]:
        """Histograms and event batches received so far, in order."""
        items = list(self._data)
        self._data.clear()
        self._queued = 0
        return items

    # Commands and replies

    def _send(self, frame):
        try:
            self.serial.write(frame)
            self.serial.flush()
        except (serial.SerialException, OSError, termios.error) as error:
            self._lost(error)

    def command(self, type: PacketType, payload: bytes = b"", *,
                expect: Callable[[Packet], bool], what: Optional[str] = None) -> Packet:
        """Send a command and return the reply that ``expect(packet)`` accepts.

        ``expect`` gets each reply (not ACK/NAK for this command: those are handled here) and
        returns True for the one wanted. ACK with this command's sequence number returns that
        ACK. NAK with its sequence number raises :exc:`BoardRefused`; a NAK for a link error
        means the command arrived damaged, and it is re-sent at once.
        """
        what = what or type.name
        seq = self.encoder.seq
        frame = self.encoder.frame(type, payload)
        attempts = self.retries + 1
        for attempt in range(attempts):
            if attempt:
                self._not_answering(what)
                self.retransmissions += 1
                _logger.info("no valid reply to %s (seq %d), re-sending (attempt %d of %d)",
                             what, seq, attempt + 1, attempts)
            self._send(frame)
            deadline = time.monotonic() + self.timeout_s
            resend = False
            while not resend:
                while self._replies:
                    reply = self._replies.popleft()
                    if reply.type == PacketType.NAK and len(reply.payload) == byte_size(Nak):
                        nak = unpack(Nak, reply.payload)
                        nak_seq, code, detail = nak["seq"], nak["code"], nak["detail"]
                        if code in _LINK_CODES:
                            self.link_naks += 1
                            resend = True
                            continue
                        if nak_seq == seq:
                            raise _refused(what, code, detail)
                        self.stale_replies += 1
                        continue
                    self._answered = True
                    if reply.type == PacketType.ACK and len(reply.payload) == 1 \
                            and reply.payload[0] == seq:
                        return reply
                    if expect(reply):
                        self.last_reply = reply
                        return reply
                    self.stale_replies += 1
                if resend:
                    break
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                self.poll(min(remaining, 0.05))
        raise BoardLost(f"the board on {self.port_name} does not answer ({what}: no reply in "
                        f"{attempts} attempts of {self.timeout_s:g} s); is it connected and "
                        f"powered, and is the baud rate right?")


def _refused(what, code, detail):
    # The BoardRefused for a NAK of ``what`` with ``code`` (a number) and ``detail``.
    try:
        code = NakCode(code)
        name = code.name
    except ValueError:
        name = f"code {code:#04x}"
    register = None
    if code in (NakCode.OUT_OF_RANGE, NakCode.BAD_ADDRESS):
        register = BY_ADDRESS.get(detail)
    if code == NakCode.OUT_OF_RANGE:
        if detail == CONSISTENCY:
            reason = "the settings would be inconsistent"
        else:
            reason = f"{register.name if register else detail} out of range"
        message = f"the board refused {what}: {reason} ({name})"
    elif code == NakCode.BAD_ADDRESS:
        message = f"the board refused {what}: no register at address {detail:#06x}" + \
            (f" ({register.name})" if register else "")
    else:
        message = f"the board refused {what} ({name}, detail {detail})"
    return BoardRefused(message, command=what, code=code, detail=detail, register=register)
