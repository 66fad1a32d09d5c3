"""Model of :class:`fliss.hdl.link.command.CommandProcessor`: packets in, replies out."""

from ...hdl.protocol import (PROTOCOL_VERSION, GATEWARE_MAJOR, GATEWARE_MINOR, GATEWARE_PATCH,
                             PacketType, NakCode,
                             Identity, Nak, ReadRequest, Status, STATUS_FIELDS, READ_MAX,
                             CONSISTENCY, REGISTER_BYTES, registers_layout)
from ...hdl.registers import (REGISTERS, BY_ADDRESS, KEYING, TdcSource, defaults, problems,
                              register_maxima, iv_problem, value_of, words_of)
from ...hdl.delay.modes import mode_row
from ...hdl.delay.settings import BANK_BITS
from ...protocol.layout import pack, unpack, byte_size, unpack_words
from ...hdl.finetdc.table import nominal_table
from .delay import KeyedRestarts


__all__ = ["CommandModel", "identity_bytes"]


def identity_bytes(clock_hz, baud, bank_bits=BANK_BITS):
    return pack(Identity, protocol=PROTOCOL_VERSION, gateware_major=GATEWARE_MAJOR,
                gateware_minor=GATEWARE_MINOR, gateware_patch=GATEWARE_PATCH, registers=len(REGISTERS), clock_hz=int(clock_hz),
                baud=int(baud), bank_bits=int(bank_bits))


class CommandModel:
    """Register file and replies, command by command.

    :meth:`command` takes a packet ``(type, seq, payload)`` and returns the reply
    ``(type, payload)``; :meth:`link_error` the reply to a dropped frame. ``maxima`` lowers
    register maxima as in :class:`~fliss.hdl.link.command.CommandProcessor`; ``bank_bits`` is the
    histogram bank's (its pixel split check, and the identity).

    ``keyed_source``: the board has a delay core with the keyed source (a whole board; not the
    command side alone, whose IV in use stays 0). The IV registers read its IV in use
    (:attr:`restarts`, :class:`~fliss.sim.models.delay.KeyedRestarts`); a run in keyed mode is taken
    to use its keystream (commands take far longer than a start), and STATUS ``ivs_used_up``
    says when the source has used every IV under its key.

    The fine TDC's calibration table (:attr:`table`, a build with the fine TDC: ``tdc_source``
    up to 3) is reached as in the gateware: a WRITE of ``table_address`` moves its pointer, each
    WRITE of ``table_data`` writes the entry at the pointer and moves it on, and a READ of
    ``table_data`` gives the entry at the pointer.
    """

    def __init__(self, clock_hz, baud, maxima=None, keyed_source=False, bank_bits=BANK_BITS):
        self.clock_hz, self.baud = clock_hz, baud
        self.bank_bits = bank_bits
        self.maxima = register_maxima(maxima, clock_hz)
        self.settings = defaults(clock_hz)
        self.running = False
        self.commands = 0
        self.refused = 0
        self.keyed_source = keyed_source
        self.restarts = KeyedRestarts()
        # The table: a build with the fine TDC (one without it reads table_data as its 0)
        self.fine_tdc = self.maxima["tdc_source"] >= TdcSource.FINE.value
        self.table = nominal_table()
        self.table_pointer = 0

    @property
    def iv_in_use(self):
        return self.restarts.iv if self.keyed_source else 0

    @property
    def ivs_used_up(self):
        """STATUS ``ivs_used_up``: the keyed source has used every IV under its key."""
        return self.keyed_source and self.restarts.spent

    @property
    def no_pulses(self):
        """The victim fires no pulse (nor TDC start) when started: its mode is keyed and its
        source has used every IV under its key."""
        return self.ivs_used_up and self._keyed_mode

    @property
    def _keyed_mode(self):
        row = mode_row(self.settings["delay_mode"])
        return row is not None and row.keyed

    def _keyed_load(self):
        # A load of the delay source (every cycle while stopped, on update while running)
        if self.keyed_source:
            self.restarts.load(keyed=self._keyed_mode)
            if self.running and self._keyed_mode:
                self.restarts.take()

    def read_value(self, register):
        """What a READ of ``register`` gives: 0 for the key, the IV in use for the IV."""
        if register.write_only:
            return 0
        if register.in_use:
            return words_of(self.iv_in_use, "iv")[register.name]
        if register.name == "table_data" and self.fine_tdc:
            return self.table[self.table_pointer]
        return self.settings[register.name]

    def _table_access(self, written):
        # The calibration table's pointer (moved first when a WRITE has both) and entry
        if "table_address" in written:
            self.table_pointer = self.settings["table_address"]
        if "table_data" in written:
            self.table[self.table_pointer] = self.settings["table_data"]
            self.table_pointer = (self.table_pointer + 1) % len(self.table)

    def _nak(self, seq, code, detail=0):
        self.refused += 1
        return PacketType.NAK, pack(Nak, seq=seq, code=code, detail=detail)

    def link_error(self, code):
        return PacketType.NAK, pack(Nak, code=code)

    def command(self, type, seq, payload, status=None):
        self.commands += 1
        length = len(payload)
        if type in (PacketType.PING.value, PacketType.START.value, PacketType.STOP.value,
                    PacketType.IDENTIFY.value, PacketType.GET_STATUS.value) and length:
            return self._nak(seq, NakCode.BAD_PAYLOAD)
        if type == PacketType.PING.value:
            return PacketType.ACK, bytes([seq])
        if type == PacketType.IDENTIFY.value:
            return PacketType.IDENTITY, identity_bytes(self.clock_hz, self.baud, self.bank_bits)
        if type in (PacketType.START.value, PacketType.STOP.value):
            self.running = type == PacketType.START.value
            self._keyed_load()
            return PacketType.ACK, bytes([seq])
        if type == PacketType.GET_STATUS.value:
            counters = dict.fromkeys(STATUS_FIELDS, 0)
            counters.update(status or {})
            counters.update(running=int(self.running), commands=self.commands,
                            refused=self.refused)
            if self.keyed_source:
                counters["ivs_used_up"] = int(self.ivs_used_up)
            return PacketType.STATUS, pack(Status, {f: counters[f] for f in STATUS_FIELDS})
        if type == PacketType.READ.value:
            if length != byte_size(ReadRequest):
                return self._nak(seq, NakCode.BAD_PAYLOAD)
            request = unpack(ReadRequest, payload)
            address, count = request["address"], request["count"]
            if count == 0 or count > READ_MAX or address + count > len(REGISTERS):
                return self._nak(seq, NakCode.BAD_ADDRESS, address)
            values = [self.read_value(REGISTERS[address + k]) for k in range(count)]
            return PacketType.REGISTERS, pack(registers_layout(count), address=address,
                                              values=values)
        if type == PacketType.WRITE.value:
            start = byte_size(registers_layout(0))
            if length < start + REGISTER_BYTES or (length - start) % REGISTER_BYTES:
                return self._nak(seq, NakCode.BAD_PAYLOAD)
            address = unpack(registers_layout(0), payload[:start])["address"]
            values = unpack_words(payload, offset=start)
            candidate = dict(self.settings)
            written = []
            for offset, value in enumerate(values):
                register = BY_ADDRESS.get((address + offset) & 0xffff)
                if register is None:
                    return self._nak(seq, NakCode.BAD_ADDRESS, (address + offset) & 0xffff)
                if not register.minimum <= value <= self.maxima[register.name]:
                    return self._nak(seq, NakCode.OUT_OF_RANGE, register.address)
                candidate[register.name] = value
                written.append(register.name)
            keyed = any(self.maxima[r.name] for r in KEYING.members)    # (else no IV rule)
            if problems(candidate, self.bank_bits, keyed) or \
                    keyed and iv_problem(written, candidate, self.iv_in_use):
                return self._nak(seq, NakCode.OUT_OF_RANGE, CONSISTENCY)
            self.settings = candidate
            self._table_access(written)
            if {r.name for r in KEYING.members} & set(written):
                self.restarts.write(key=value_of(candidate, "key"), iv=value_of(candidate, "iv"))
            self._keyed_load()
            return PacketType.ACK, bytes([seq])
        return self._nak(seq, NakCode.UNKNOWN_TYPE, type)
