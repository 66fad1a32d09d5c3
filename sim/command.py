"""Model of :class:`fliss.hdl.command.CommandProcessor`: packets in, replies out."""

import struct

from ..hdl.command import (Identity, STATUS_FIELDS, READ_MAX, CONSISTENCY, _version,
                           register_maxima)
from ..hdl.protocol import PROTOCOL_VERSION, PacketType, NakCode
from ..hdl.registers import REGISTERS, BY_ADDRESS, defaults, problems
from .. import __version__


__all__ = ["CommandModel", "identity_bytes"]


def identity_bytes(clock_hz, baud):
    major, minor = _version(__version__)
    return struct.pack("<BBBBII", PROTOCOL_VERSION, major, minor, len(REGISTERS),
                       int(clock_hz), int(baud))


class CommandModel:
    """Register file and replies, command by command.

    :meth:`command` takes a packet ``(type, seq, payload)`` and returns the reply
    ``(type, payload)``; :meth:`link_error` the reply to a dropped frame. ``maxima`` lowers
    register maxima as in :class:`~fliss.hdl.command.CommandProcessor`.
    """

    def __init__(self, clock_hz, baud, maxima=None):
        self.clock_hz, self.baud = clock_hz, baud
        self.maxima = register_maxima(maxima, clock_hz)
        self.settings = defaults(clock_hz)
        self.running = False
        self.commands = 0
        self.refused = 0

    def _nak(self, seq, code, detail=0):
        self.refused += 1
        return PacketType.NAK, struct.pack("<BBH", seq, code.value, detail)

    def link_error(self, code):
        return PacketType.NAK, struct.pack("<BBH", 0, code.value, 0)

    def command(self, type, seq, payload, status=None):
        self.commands += 1
        length = len(payload)
        if type in (PacketType.PING.value, PacketType.START.value, PacketType.STOP.value,
                    PacketType.IDENTIFY.value, PacketType.GET_STATUS.value) and length:
            return self._nak(seq, NakCode.BAD_PAYLOAD)
        if type == PacketType.PING.value:
            return PacketType.ACK, bytes([seq])
        if type == PacketType.IDENTIFY.value:
            return PacketType.IDENTITY, identity_bytes(self.clock_hz, self.baud)
        if type in (PacketType.START.value, PacketType.STOP.value):
            self.running = type == PacketType.START.value
            return PacketType.ACK, bytes([seq])
        if type == PacketType.GET_STATUS.value:
            counters = dict.fromkeys(STATUS_FIELDS, 0)
            counters.update(status or {})
            counters.update(running=int(self.running), commands=self.commands,
                            refused=self.refused)
            return PacketType.STATUS, struct.pack(f"<{len(STATUS_FIELDS)}I",
                                                  *(counters[f] for f in STATUS_FIELDS))
        if type == PacketType.READ.value:
            if length != 3:
                return self._nak(seq, NakCode.BAD_PAYLOAD)
            address, count = struct.unpack("<HB", payload)
            if count == 0 or count > READ_MAX or address + count > len(REGISTERS):
                return self._nak(seq, NakCode.BAD_ADDRESS, address)
            values = [self.settings[REGISTERS[address + k].name] for k in range(count)]
            return PacketType.REGISTERS, struct.pack(f"<H{count}I", address, *values)
        if type == PacketType.WRITE.value:
            if length < 6 or (length - 2) % 4:
                return self._nak(seq, NakCode.BAD_PAYLOAD)
            address, = struct.unpack_from("<H", payload)
            values = struct.unpack_from(f"<{(length - 2) // 4}I", payload, 2)
            candidate = dict(self.settings)
            for offset, value in enumerate(values):
                register = BY_ADDRESS.get((address + offset) & 0xffff)
                if register is None:
                    return self._nak(seq, NakCode.BAD_ADDRESS, (address + offset) & 0xffff)
                if not register.minimum <= value <= self.maxima[register.name]:
                    return self._nak(seq, NakCode.OUT_OF_RANGE, register.address)
                candidate[register.name] = value
            if problems(candidate):
                return self._nak(seq, NakCode.OUT_OF_RANGE, CONSISTENCY)
            self.settings = candidate
            return PacketType.ACK, bytes([seq])
        return self._nak(seq, NakCode.UNKNOWN_TYPE, type)
