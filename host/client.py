"""Serial client of a FLISS board: commands, registers, and the data stream.

:class:`BoardClient` opens a port with :func:`serial.serial_for_url`, so a device path
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
is matched by what it answers: an ACK or NAK by the sequence number in its payload, IDENTITY,
REGISTERS and STATUS by their type (and address).
The Python API, :mod:`fliss.host.board`, is the layer above: settings in units, numpy arrays.
Everything that goes wrong raises a :exc:`~fliss.host.errors.BoardError` (the board is lost,
refused a command, is of another protocol version; settings refused on the host) with one line
that says what and what to do.
"""

import logging
import math
import time
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable, Dict, Iterable, Iterator, List, Mapping, Optional, Union

import serial

from ..hdl.protocol import (PROTOCOL_VERSION, DEFAULT_BAUD, PacketType, NakCode, DELIMITER,
                            Identity, Nak, ReadRequest, Status, READ_MAX, CONSISTENCY, LINK_ERRORS,
                            registers_layout)
from ..hdl.registers import REGISTERS, BY_NAME, BY_ADDRESS, problems, split_problems
from ..hdl.delay.settings import BANK_BITS, MAX_BANK_BITS
from ..protocol.frames import LinkCounters, Packet, PacketEncoder
from ..protocol.layout import byte_size, pack, unpack
from ..protocol.packets import DATA_TYPES
from .bulk import BulkDecoder
from .errors import BoardLost, BoardMismatch, BoardRefused, SettingsError
from .port import default_timeout, open_port
from .stream import EventBatch, HistogramFrame, StreamAssembler, StreamCounters


__all__ = ["IdentityInfo", "BoardClient"]


_logger = logging.getLogger(__name__)

_LINK_CODES = {code.value for code in LINK_ERRORS}


@dataclass(frozen=True)
class IdentityInfo:
    """What the IDENTITY packet says."""
    protocol: int
    gateware_version: str
    registers: int
    clock_hz: int
    baud: int
    #: The histogram bank holds ``2**bank_bits`` bins (the pixel split must fit it).
    bank_bits: int = BANK_BITS

    def as_dict(self) -> Dict[str, Any]:
        return {"protocol": self.protocol, "gateware_version": self.gateware_version,
                "registers": self.registers, "clock_hz": self.clock_hz, "baud": self.baud,
                "bank_bits": self.bank_bits}


class BoardClient:
    """A FLISS board on a serial port.

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
    """

    def __init__(self, port: str, *, baud: int = DEFAULT_BAUD, timeout_s: Optional[float] = None,
                 retries: int = 3, serial_port: Optional[serial.SerialBase] = None) -> None:
        self.port_name = port
        self.timeout_s = float(default_timeout(port) if timeout_s is None else timeout_s)
        self.retries = int(retries)
        self.serial = open_port(port, baud) if serial_port is None else serial_port
        self.decoder = BulkDecoder(synced=False)
        self.encoder = PacketEncoder()
        self.assembler = StreamAssembler()
        self._identity = None
        self._answered = False      # any reply yet (a silent board is reported once)
        self.retransmissions = 0
        self.link_naks = 0
        self.stale_replies = 0
        #: The last reply :meth:`command` returned (other than an ACK).
        self.last_reply = None
        self._replies = deque()
        self._data = deque()
        self._last_rx = self._last_data = time.monotonic()
        self._baseline = {}
        try:
            try:
                self.serial.reset_input_buffer()
            except (serial.SerialException, OSError) as error:
                self._lost(error)
            self._sync()
        except BaseException:
            self.close()
            raise

    @property
    def identity(self) -> IdentityInfo:
        """The board's :class:`IdentityInfo` (:meth:`identify` reads it when first needed)."""
        if self._identity is None:
            self.identify()
        return self._identity

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
        except (serial.SerialException, OSError) as error:
            self._lost(error)
        if data:
            self._last_rx = time.monotonic()
            now = time.time()
            decoded = self.decoder.feed_events(data)
            for item in decoded.items:
                if isinstance(item, Packet):
                    if item.type in DATA_TYPES:
                        self._last_data = self._last_rx
                        self._data.extend(self.assembler.add(item, now))
                    else:
                        self._replies.append(item)
            for events in decoded.batches():
                self._last_data = self._last_rx
                self._data.extend(self.assembler.add_events(events, now))
        return len(data)

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
        return items

    # Commands

    def _send(self, frame):
        try:
            self.serial.write(frame)
            self.serial.flush()
        except (serial.SerialException, OSError) as error:
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

    def ping(self) -> None:
        self.command(PacketType.PING, expect=lambda reply: False)

    def identify(self, *, check: bool = True) -> IdentityInfo:
        """Read the identity; with ``check``, refuse a board with another protocol version."""
        reply = self.command(PacketType.IDENTIFY, expect=lambda r: r.type == PacketType.IDENTITY)
        if len(reply.payload) != byte_size(Identity):
            raise BoardMismatch(f"the board sent an identity of {len(reply.payload)} bytes, not "
                             f"{byte_size(Identity)}: is it a FLISS board?")
        fields = unpack(Identity, reply.payload)
        protocol, registers = fields["protocol"], fields["registers"]
        self._identity = IdentityInfo(protocol,
                                     f"{fields['gateware_major']}.{fields['gateware_minor']}",
                                     registers, fields["clock_hz"], fields["baud"],
                                     fields["bank_bits"])
        if check and protocol != PROTOCOL_VERSION:
            raise BoardMismatch(f"the board speaks protocol version {protocol}, this fliss speaks "
                             f"version {PROTOCOL_VERSION}: update the "
                             f"{'gateware' if protocol < PROTOCOL_VERSION else 'host tool'}")
        if check and registers != len(REGISTERS):
            raise BoardMismatch(f"the board has {registers} registers, this fliss knows "
                             f"{len(REGISTERS)}: gateware and host tool do not match")
        return self._identity

    @property
    def clock_hz(self) -> int:
        """The board's clock frequency in Hz (from its identity)."""
        return self.identity.clock_hz

    def read_registers(self, names: Optional[Iterable[str]] = None) -> Dict[str, int]:
        """Register values by name (all of them by default), read in as few READs as possible."""
        names = [register.name for register in REGISTERS] if names is None else list(names)
        for name in names:
            if name not in BY_NAME:
                raise SettingsError(f"no register named {name!r}")
        addresses = sorted(BY_NAME[name].address for name in names)
        values = {}
        while addresses:
            first = addresses[0]
            count = min(addresses[-1] - first + 1, READ_MAX)
            payload = pack(ReadRequest, address=first, count=count)
            layout = registers_layout(count)

            def expect(reply, first=first, layout=layout):
                return reply.type == PacketType.REGISTERS and \
                    len(reply.payload) == byte_size(layout) and \
                    unpack(layout, reply.payload)["address"] == first

            reply = self.command(PacketType.READ, payload, expect=expect, what="READ")
            words = unpack(layout, reply.payload)["values"]
            for offset, word in enumerate(words):
                values[BY_ADDRESS[first + offset].name] = word
            addresses = [a for a in addresses if a >= first + count]
        return {name: values[name] for name in names}

    def check_settings(self, current: Mapping[str, int],
                       changes: Mapping[str, int]) -> Dict[str, int]:
        """The settings ``current`` with ``changes`` applied, if every value is in range and
        the whole is consistent (:func:`fliss.hdl.registers.problems`, with the board's
        histogram bank from its identity); else :exc:`~fliss.host.errors.SettingsError`."""
        candidate = dict(current)
        for name, value in changes.items():
            if name not in BY_NAME:
                raise SettingsError(f"no register named {name!r}")
            try:
                BY_NAME[name].check(value)
            except ValueError as error:
                raise SettingsError(str(error)) from None
            candidate[name] = value
        # (the board's histogram bank from its identity, asked for only when the split changes)
        found = problems(candidate, MAX_BANK_BITS)
        if not found and {"pixel_bits", "bin_shift"} & set(changes):
            found = split_problems(candidate, self.identity.bank_bits)
        if found:
            raise SettingsError("; ".join(found))
        return candidate

    def write_registers(self, changes: Mapping[str, int], *,
                        current: Optional[Mapping[str, int]] = None) -> Dict[str, int]:
        """Write registers by name, after checking range and consistency on the host.

        All registers from the lowest to the highest address changed go in one WRITE, which
        the board applies all at once or not at all. Returns the new settings.
        """
        if not changes:
            return dict(current) if current is not None else self.read_registers()
        if current is None:
            current = self.read_registers()
        candidate = self.check_settings(current, changes)
        addresses = [BY_NAME[name].address for name in changes]
        first, last = min(addresses), max(addresses)
        values = [candidate[BY_ADDRESS[a].name] for a in range(first, last + 1)]
        payload = pack(registers_layout(len(values)), address=first, values=values)
        try:
            self.command(PacketType.WRITE, payload, expect=lambda reply: False, what="WRITE")
        except BoardRefused as error:
            # Every value passed the register map's range here: a refusal of one is a board
            # whose build takes less (no raw events, no aggressor, narrower settings).
            register = error.register
            if error.code != NakCode.OUT_OF_RANGE or register is None:
                raise
            raise BoardRefused(f"the board refused WRITE: its build does not take "
                               f"{register.name} = {candidate[register.name]} (a smaller build, "
                               f"such as the iCEBreaker's, leaves out some features and "
                               f"narrows some ranges: see docs/boards.md)", command="WRITE",
                               code=error.code, detail=error.detail, register=register) from None
        return candidate

    def start(self) -> None:
        self.command(PacketType.START, expect=lambda reply: False)

    def stop(self) -> None:
        self.command(PacketType.STOP, expect=lambda reply: False)

    def status(self) -> Dict[str, int]:
        """Board counters, a dict in :data:`~fliss.hdl.protocol.STATUS_FIELDS` order."""
        reply = self.command(PacketType.GET_STATUS,
                             expect=lambda r: r.type == PacketType.STATUS and
                             len(r.payload) == byte_size(Status), what="GET_STATUS")
        return unpack(Status, reply.payload)

    # Streaming

    def stream(self, *, idle_timeout_s: float = 2.0, poll_s: float = 0.05,
               data_timeout_s: float = math.inf
               ) -> Iterator[Union[HistogramFrame, EventBatch, None]]:
        """Yield :class:`HistogramFrame` and :class:`EventBatch` items as they arrive, forever;
        between items it yields ``None`` about every ``poll_s`` so a caller can update a
        progress display or stop (:meth:`fliss.host.board.Board.stream` yields histograms
        only). Raises :exc:`BoardLost` when no byte arrives for
        ``idle_timeout_s``, when no data packet arrives for ``data_timeout_s`` (a board that
        answers commands but has stopped acquiring), or when the port goes away."""
        self._last_rx = self._last_data = time.monotonic()
        while True:
            if self._data:
                yield self._data.popleft()
                continue
            self.poll(poll_s)
            if self._data:
                continue
            if self.idle_s > idle_timeout_s:
                raise BoardLost(f"the board on {self.port_name} stopped sending (nothing for "
                                f"{idle_timeout_s:g} s during an acquisition)")
            if time.monotonic() - self._last_data > data_timeout_s:
                raise BoardLost(f"the board on {self.port_name} answers but sent no data for "
                                f"{data_timeout_s:g} s during an acquisition")
            yield None

    def settle(self, limit_s: float = 120.0, give_up_s: float = 3.0,
               frames_at_start: Optional[int] = None
               ) -> List[Union[HistogramFrame, EventBatch]]:
        """After a STOP: read until every histogram the board completed has arrived (its STATUS
        ``frames`` count; with ``frames_at_start``, its count at the last :meth:`reset_counters`,
        as many frames as it made since: histograms and depth frames are numbered apart), until
        nothing more has come for ``give_up_s`` (a histogram lost on a noisy line), or until
        ``limit_s``; returns everything received. A board slow to send its last histogram (a
        simulation, a slow link) is waited for rather than left to spill into the next capture."""
        end = time.monotonic() + limit_s
        items = []
        last = time.monotonic()
        while True:
            received = self.drain(quiet_s=0.3, limit_s=max(0.5, end - time.monotonic()))
            items += received
            frames = self.status()["frames"]
            ended = self.assembler.frames_ended
            arrived = self.assembler.counters.frames + self.assembler.counters.depth_frames
            if frames == 0 or ended == frames or time.monotonic() > end or (
                    frames_at_start is not None and arrived >= frames - frames_at_start):
                return items
            if ended is None and not items:
                return items   # nothing of this capture's histograms: not ours to wait for
            if received:
                last = time.monotonic()
            elif time.monotonic() - last > give_up_s:
                # Nothing more came: the rest was lost on the way (or is not ours to wait for).
                return items

    def drain(self, quiet_s: float = 0.3, limit_s: float = 10.0
              ) -> List[Union[HistogramFrame, EventBatch]]:
        """Read until nothing has arrived for ``quiet_s`` (at most ``limit_s``), then finish the
        histogram in progress; returns everything received."""
        end = time.monotonic() + limit_s
        self._last_rx = time.monotonic()
        while time.monotonic() < end and self.idle_s < quiet_s:
            self.poll(min(quiet_s, 0.05))
        self._data.extend(self.assembler.flush())
        return self.take_data()


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
