"""Serial client of a FLISS board: its commands and registers, and its data stream.

:class:`BoardClient` speaks to a board over a :class:`~fliss.host.link.BoardLink` (the port,
frames, replies matched to commands and re-sent when lost, data packets assembled): it reads the
identity, reads and writes registers (checked for range and consistency on the host first),
starts and stops acquisitions, reads the status counters, and yields the histograms and event
batches of an acquisition as they arrive.
The Python API, :mod:`fliss.host.board`, is the layer above: settings in units, numpy arrays.
Everything that goes wrong raises a :exc:`~fliss.host.errors.BoardError` (the board is lost,
refused a command, is of another protocol version; settings refused on the host) with one line
that says what and what to do.
"""

import math
import time
import warnings
from dataclasses import dataclass
from typing import Any, Dict, Iterable, Iterator, List, Mapping, Optional, Union

from ..hdl.protocol import (PROTOCOL_VERSION, GATEWARE_VERSION, version_numbers, PacketType,
                            NakCode, Identity, ReadRequest, Status, READ_MAX, registers_layout)
from ..hdl.registers import REGISTERS, BY_NAME, BY_ADDRESS, problems, split_problems
from ..hdl.delay.settings import BANK_BITS, MAX_BANK_BITS
from ..protocol.layout import byte_size, pack, unpack
from .errors import (BoardLost, BoardMismatch, BoardRefused, GatewareVersionWarning,
                     SettingsError)
from .link import BoardLink
from .stream import EventBatch, HistogramFrame


__all__ = ["IdentityInfo", "BoardClient"]


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


class BoardClient(BoardLink):
    """A FLISS board on a serial port (the parameters are :class:`~fliss.host.link.BoardLink`'s:
    ``port``, ``baud``, ``timeout_s``, ``retries``, ``serial_port``)."""

    _identity = None        # (until :meth:`identify` reads it)

    @property
    def identity(self) -> IdentityInfo:
        """The board's :class:`IdentityInfo` (:meth:`identify` reads it when first needed)."""
        if self._identity is None:
            self.identify()
        return self._identity

    # Commands

    def ping(self) -> None:
        self.command(PacketType.PING, expect=lambda reply: False)

    def identify(self, *, check: bool = True) -> IdentityInfo:
        """Read the identity; with ``check``, refuse a board with another protocol version or
        register map, and warn (:exc:`~fliss.host.errors.GatewareVersionWarning`) of gateware
        of another version than this package's."""
        reply = self.command(PacketType.IDENTIFY, expect=lambda r: r.type == PacketType.IDENTITY)
        # The protocol byte comes first in every version's identity: a board of another
        # protocol is told so, whatever the length of its identity.
        protocol = reply.payload[0] if reply.payload else None
        if check and protocol is not None and protocol != PROTOCOL_VERSION:
            raise BoardMismatch(f"the board speaks protocol version {protocol}, this fliss speaks "
                                f"version {PROTOCOL_VERSION}: update the "
                                f"{'gateware' if protocol < PROTOCOL_VERSION else 'host tool'}")
        if len(reply.payload) != byte_size(Identity):
            raise BoardMismatch(f"the board sent an identity of {len(reply.payload)} bytes, not "
                                f"{byte_size(Identity)}: is it a FLISS board?")
        fields = unpack(Identity, reply.payload)
        registers = fields["registers"]
        version = (fields["gateware_major"], fields["gateware_minor"], fields["gateware_patch"])
        self._identity = IdentityInfo(protocol, ".".join(map(str, version)), registers,
                                      fields["clock_hz"], fields["baud"], fields["bank_bits"])
        if check and registers != len(REGISTERS):
            raise BoardMismatch(f"the board has {registers} registers, this fliss knows "
                                f"{len(REGISTERS)}: gateware and host tool do not match")
        if check and version != version_numbers(GATEWARE_VERSION):
            warnings.warn(GatewareVersionWarning(
                f"the board runs gateware {self._identity.gateware_version}, this fliss is "
                f"{GATEWARE_VERSION}: program the board with this version's bitstream "
                f"(make bitstream)"), stacklevel=2)
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
        return self.write_checked(self.check_settings(current, changes), changes)

    def write_checked(self, candidate: Mapping[str, int],
                      changes: Iterable[str]) -> Dict[str, int]:
        """Write the registers named in ``changes`` with their values in ``candidate``, the
        settings they make, already checked (:meth:`check_settings`, or
        :func:`fliss.host.settings.convert`, which checks as it does and names the settings as
        the caller wrote them), in one WRITE. Returns ``candidate``."""
        candidate = dict(candidate)
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
                yield self.next_data()
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
            arrived = self.assembler.frames_arrived
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
        return self.take_data() + self.assembler.flush()
