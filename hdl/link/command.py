"""Command processor: verified packets in, replies out, the register file in between."""

from amaranth.hdl import C, Cat, Const, Module, Mux, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ..clock import DEFAULT_CLOCK_HZ
from .buffer import StreamBuffer
from .framing import PacketBeat
from ..protocol import (PROTOCOL_VERSION, GATEWARE_MAJOR, GATEWARE_MINOR, GATEWARE_PATCH,
                        PacketType, NakCode,
                        MAX_PAYLOAD, COUNTER_BITS, Identity, Nak, STATUS_FIELDS, READ_MAX,
                        CONSISTENCY)
from ..regfile import RegisterFile
from ..registers import REGISTERS, register_maxima
from ..delay.settings import BANK_BITS


__all__ = ["StatusSignature", "CommandProcessor"]


#: The command processor's port to the STATUS counters (:class:`fliss.hdl.status.StatusCounters`):
#: ``capture`` (a strobe) asks for a snapshot of all the counters; ``ready`` is high when no
#: snapshot is being taken (it falls in the cycle after ``capture`` at the latest); ``data`` is
#: field ``addr`` of :data:`STATUS_FIELDS` in the snapshot, one cycle after ``addr``.
StatusSignature = wiring.Signature({
    "capture": Out(1),
    "ready":   In(1),
    "addr":    Out(range(len(STATUS_FIELDS))),
    "data":    In(COUNTER_BITS),
})


class CommandProcessor(wiring.Component):
    """Command processor, around its register file.

    Takes verified packets (from :class:`~fliss.hdl.link.framing.FrameDecoder`) and answers each
    command with one packet: ``ACK``, ``NAK`` with a :class:`~fliss.hdl.protocol.NakCode`, or the
    data asked for. A ``WRITE`` carries an address and one u32 per register; every value is
    range-checked, the settings it would make are checked together
    (:func:`fliss.hdl.registers.problems`), and then either all are applied at once or none.
    Link errors reported by the frame decoder are answered with a ``NAK`` (sequence number 0).

    Outgoing packets carry sequence number 0: the transmit side numbers them.

    Parameters
    ----------
    clock_hz : int
        Clock frequency, for the register reset values and the identity.
    baud : int
        Baud rate, for the identity.
    maxima : dict
        Register name -> a lower maximum than the register map's, for a build that lacks a
        feature (``{"aggressor_delay_mode": 0}`` without the aggressor's delay source). A value
        above it is refused as out of range.
    bank_bits : int
        Width of the histogram bank's address, for the pixel split check (a split that does
        not fit is refused as inconsistent) and the identity.

    Members
    -------
    packets : In(stream.Signature(PacketBeat))
        Verified packets.
    replies : Out(stream.Signature(PacketBeat))
        Replies.
    link_error : In(1)
        Strobe: the frame decoder dropped a frame.
    link_error_code : In(NakCode)
        Why, with ``link_error``.
    update : Out(1)
        Strobe: settings changed while running; in the cycle after ``settings`` changed (a
        register, for timing).
    running : Out(1)
        Acquisition started.
    status : Out(StatusSignature)
        The counters of STATUS replies; ``running`` is filled in here.
    tally : Out(data.StructLayout({"commands": 1, "refused": 1}))
        Strobes for the ``commands`` and ``refused`` counters: a command received, a command
        refused with a NAK.
    """

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, baud=115_200, maxima=None,
                 bank_bits=BANK_BITS):
        self.clock_hz = int(clock_hz)
        self.baud = int(baud)
        self.maxima = register_maxima(maxima, self.clock_hz)
        #: The register file (:class:`~fliss.hdl.regfile.RegisterFile`), a submodule.
        self.registers = RegisterFile(clock_hz=self.clock_hz, maxima=self.maxima,
                                      bank_bits=bank_bits)
        self.bank_bits = self.registers.bank_bits
        super().__init__({
            "packets":         In(stream.Signature(PacketBeat)),
            "replies":         Out(stream.Signature(PacketBeat)),
            "link_error":      In(1),
            "link_error_code": In(NakCode, init=NakCode.BAD_CRC),
            "update":          Out(1),
            "running":         Out(1),
            "status":          Out(StatusSignature),
            "tally":           Out(data.StructLayout({"commands": 1, "refused": 1})),
        })

    def elaborate(self, platform):
        m = Module()

        # Replies leave through a register slice: the byte multiplexers below end there. Half
        # rate (a beat every other cycle, half the flip-flops) is plenty for a UART link.
        m.submodules.reply_buffer = reply_buffer = StreamBuffer(PacketBeat, full_rate=False)
        wiring.connect(m, reply_buffer.o, wiring.flipped(self.replies))
        m.submodules.registers = registers = self.registers
        c = _Command(reply_buffer.i)

        with m.If(self.link_error):
            m.d.sync += c.link_pending.eq(1), c.link_code.eq(self.link_error_code)

        # WRITE values go to the register file, a cycle after they are complete (`check`).
        m.d.sync += c.check.eq(0)
        m.d.comb += [registers.value.eq(c.word), registers.check.eq(c.check)]

        m.d.sync += self.update.eq(0)
        m.d.sync += c.refusing.eq(0)
        m.d.comb += self.tally.refused.eq(c.refusing)

        # Packets are taken in IDLE and PAYLOAD: `accepting` is high in those states, a
        # register rather than decoded from the state, for timing.
        m.d.comb += self.packets.ready.eq(c.accepting)

        # The register file is read at `next_pointer` in every state (a multiplexer whose
        # select depends on the state would lengthen the path to `next_word`).
        m.d.comb += registers.read_address.eq(c.next_pointer)

        with m.FSM():
            self._parse(m, c)
            self._execute(m, c)
            self._reply(m, c)
        self._reply_bytes(m, c)

        return m

    def _parse(self, m, c):
        """States IDLE, PAYLOAD and CHECK: a command's header and payload are taken, a
        WRITE's values checked as they come, a READ's range checked; or a link error is
        answered."""
        registers = self.registers
        address_bits = (len(REGISTERS) - 1).bit_length()    # enough to address every register

        with m.State("IDLE"):
            with m.If(self.packets.valid & self.packets.p.first):
                header = self.packets.p.header
                m.d.sync += [
                    c.cmd_type.eq(header.type), c.cmd_seq.eq(header.seq),
                    c.no_payload.eq(header.length == 0),
                    c.read_payload.eq(header.length == 3),
                    c.write_payload.eq((header.length[:2] == 2) & (header.length[2:] != 0)),
                    c.index.eq(0),
                ]
                m.d.comb += [self.tally.commands.eq(1), registers.begin.eq(1)]
                with m.If(self.packets.p.last):
                    m.next = "VERDICT"
                    m.d.sync += c.accepting.eq(0)
                with m.Else():
                    m.next = "PAYLOAD"
            with m.Elif(c.link_pending):
                m.d.sync += [
                    c.link_pending.eq(0),
                    c.nak.seq.eq(0), c.nak.code.eq(c.link_code), c.nak.detail.eq(0),
                    *c.reply(PacketType.NAK, 4),
                ]
                m.next = "HEADER"
                m.d.sync += c.accepting.eq(0)

        with m.State("PAYLOAD"):
            byte = self.packets.p.data
            with m.If(self.packets.valid):
                m.d.sync += [c.index.eq(c.index + 1), c.word.eq(Cat(c.word[8:], byte))]
                with m.If(c.index == 0):
                    m.d.sync += c.address[:8].eq(byte)
                with m.If(c.index == 1):
                    m.d.sync += c.address[8:].eq(byte)
                    m.d.comb += [registers.start.eq(1),
                                 registers.start_address.eq(Cat(c.address[:8], byte))]
                with m.If(c.index == 2):
                    m.d.sync += c.count.eq(byte)
                # A WRITE value is complete: check it and put it in the candidate next.
                with m.If((c.cmd_type == PacketType.WRITE) & (c.index[:2] == 1) &
                          (c.index[2:] != 0)):
                    m.d.sync += c.check.eq(1)
                with m.If(self.packets.p.last):
                    m.next = "CHECK"
                    m.d.sync += c.accepting.eq(0)

        with m.State("CHECK"):
            # The last WRITE value is checked; the range of a READ is checked.
            # (The sum needs only the bits that can address a register.)
            m.d.sync += c.read_bad.eq((c.count == 0) | (c.count > READ_MAX) |
                                      (c.address[address_bits:] != 0) |
                                      (c.address[:address_bits] + c.count > len(REGISTERS)))
            m.next = "VERDICT"

    def _execute(self, m, c):
        """States VERDICT to COMMIT: whether the command is refused, and how; then what it does
        (a WRITE's consistency check and commit, START, STOP, a STATUS snapshot), and which
        reply it gets."""
        registers = self.registers

        with m.State("VERDICT"):
            # Whether the command is refused, and how, is decided into registers (a WRITE's
            # range errors are final only in the next cycle: it is answered in COMMIT).
            m.next = "DISPATCH"
            m.d.sync += c.refusal.eq(1)
            with m.Switch(c.cmd_type):
                with m.Case(PacketType.PING, PacketType.IDENTIFY, PacketType.START,
                            PacketType.STOP, PacketType.GET_STATUS):
                    m.d.sync += [c.refusal.eq(~c.no_payload),
                                 c.refusal_code.eq(NakCode.BAD_PAYLOAD),
                                 c.refusal_detail.eq(0)]
                with m.Case(PacketType.READ):
                    m.d.sync += [
                        c.refusal.eq(~c.read_payload | c.read_bad),
                        c.refusal_code.eq(Mux(c.read_payload, NakCode.BAD_ADDRESS,
                                              NakCode.BAD_PAYLOAD)),
                        c.refusal_detail.eq(Mux(c.read_payload, c.address, 0)),
                    ]
                with m.Case(PacketType.WRITE):
                    m.d.sync += [c.refusal.eq(~c.write_payload),
                                 c.refusal_code.eq(NakCode.BAD_PAYLOAD),
                                 c.refusal_detail.eq(0)]
                with m.Default():
                    m.d.sync += [c.refusal_code.eq(NakCode.UNKNOWN_TYPE),
                                 c.refusal_detail.eq(c.cmd_type)]

        with m.State("DISPATCH"):
            m.next = "HEADER"
            with m.If(c.refusal):
                m.d.sync += c.refuse(c.refusal_code, c.refusal_detail)
            with m.Else():
                with m.Switch(c.cmd_type):
                    with m.Case(PacketType.PING):
                        m.d.sync += c.reply(PacketType.ACK, 1)
                    with m.Case(PacketType.IDENTIFY):
                        m.d.sync += c.reply(PacketType.IDENTITY,
                                            data.Layout.cast(Identity).size // 8)
                    with m.Case(PacketType.READ):
                        m.d.sync += c.reply(PacketType.REGISTERS, Cat(C(2, 2), c.count),
                                            final=Cat(C(1, 2), c.count))
                    with m.Case(PacketType.WRITE):
                        m.next = "CONSISTENCY"
                    with m.Case(PacketType.START, PacketType.STOP):
                        m.d.sync += [
                            c.reply(PacketType.ACK, 1),
                            self.running.eq(c.cmd_type == PacketType.START),
                        ]
                    with m.Case(PacketType.GET_STATUS):
                        m.d.sync += [
                            c.reply(PacketType.STATUS, len(STATUS_FIELDS) * 4),
                            c.status_running.eq(self.running),
                        ]
                        m.d.comb += self.status.capture.eq(1)
                        m.next = "SNAPSHOT"

        with m.State("SNAPSHOT"):
            # The counters are being copied (`ready` is low from this cycle on).
            with m.If(self.status.ready):
                m.next = "HEADER"

        with m.State("CONSISTENCY"):
            m.next = "COMMIT"

        with m.State("COMMIT"):
            # `consistent` now reflects the complete candidate.
            m.next = "HEADER"
            with m.If(registers.error):
                m.d.sync += c.refuse(registers.error_code, registers.error_detail)
            with m.Elif(registers.consistent):
                m.d.comb += registers.commit.eq(1)
                m.d.sync += c.reply(PacketType.ACK, 1)
                m.d.sync += self.update.eq(self.running)
            with m.Else():
                m.d.sync += c.refuse(NakCode.OUT_OF_RANGE, CONSISTENCY)

    def _reply(self, m, c):
        """States HEADER and DATA: the reply's header beat, then its payload bytes."""
        replies = c.replies

        with m.State("HEADER"):
            m.d.comb += [
                replies.valid.eq(1),
                replies.p.first.eq(1),
                replies.p.last.eq(c.reply_length == 0),
            ]
            with m.If(replies.ready):
                m.d.sync += [
                    c.index.eq(0),
                    c.next_pointer.eq(Mux(c.is_status, 1, c.address)),
                ]
                m.next = "DATA"

        with m.State("DATA"):
            m.d.comb += [
                replies.valid.eq(1),
                replies.p.last.eq(c.index == c.reply_final),
            ]
            # READ and STATUS: the registers (counters) leave through `word`, each loaded
            # from `next_word` as the byte before it goes out (the last address byte of a
            # READ, the last byte of `running` in a STATUS, then the last byte of the one
            # before), so no wide multiplexer sits in front of the reply, and only one serves
            # all the registers. `next_word` follows `next_pointer` two cycles late (a
            # counter is read in the cycle after its address): the first is ready after the
            # first payload byte's cycle, each next one four cycles after the pointer moved.
            m.d.comb += self.status.addr.eq(c.next_pointer)
            m.d.sync += c.next_word.eq(Mux(c.is_status, self.status.data,
                                           self.registers.read_data))
            with m.If(replies.ready):
                m.d.sync += c.index.eq(c.index + 1)
                with m.If(c.index[:2] == Mux(c.is_status, 3, 1)):
                    m.d.sync += [
                        c.next_pointer.eq(c.next_pointer + 1),
                        c.word.eq(c.next_word),
                    ]
                with m.Else():
                    m.d.sync += c.word.eq(c.word >> 8)
                with m.If(c.index == c.reply_final):
                    m.next = "IDLE"
                    m.d.sync += c.accepting.eq(1)

    def _reply_bytes(self, m, c):
        """The reply's header, and its payload byte at `index`."""
        replies = c.replies
        identity = Const({"protocol": PROTOCOL_VERSION, "gateware_major": GATEWARE_MAJOR,
                          "gateware_minor": GATEWARE_MINOR, "gateware_patch": GATEWARE_PATCH,
                          "registers": len(REGISTERS),
                          "clock_hz": self.clock_hz, "baud": self.baud,
                          "bank_bits": self.bank_bits}, Identity)
        m.d.comb += [
            replies.p.header.type.eq(c.reply_type),
            replies.p.header.length.eq(c.reply_length),
        ]
        with m.Switch(c.reply_type):
            with m.Case(PacketType.ACK):
                m.d.comb += replies.p.data.eq(c.cmd_seq)
            with m.Case(PacketType.NAK):
                m.d.comb += replies.p.data.eq(c.nak.as_value().word_select(c.index[:2], 8))
            with m.Case(PacketType.IDENTITY):
                m.d.comb += replies.p.data.eq(
                    identity.as_value().word_select(c.index[:4], 8))
            with m.Case(PacketType.STATUS):
                with m.If(c.index[2:] == 0):           # index < 4
                    m.d.comb += replies.p.data.eq(Mux(c.index == 0, c.status_running, 0))
                with m.Else():
                    m.d.comb += replies.p.data.eq(c.word[:8])
            with m.Case(PacketType.REGISTERS):
                with m.If(c.index[1:] == 0):           # index < 2
                    m.d.comb += replies.p.data.eq(c.address.word_select(c.index[0], 8))
                with m.Else():
                    m.d.comb += replies.p.data.eq(c.word[:8])


class _Command:
    """The registers that the paragraphs of :meth:`CommandProcessor.elaborate` share: the
    command being received (parse), how it is refused (execute), and the reply being sent
    (reply), with ``replies``, the reply stream into the register slice."""

    def __init__(self, replies):
        self.replies = replies
        # Command being received
        self.cmd_type = Signal(8)
        self.cmd_seq = Signal(8)
        # Payload length checks of the command, registered with its header
        self.no_payload = Signal()          # length 0
        self.read_payload = Signal()        # length 3: address and count
        self.write_payload = Signal()       # length 2 + 4 n, n >= 1: address and n values
        # Payload byte, in and out. (Its comparisons with constants are tests of its high bits
        # where they can be: as comparators they would be carry chains.)
        self.index = Signal(range(MAX_PAYLOAD + 1))
        self.address = Signal(16)
        self.count = Signal(8)
        self.read_bad = Signal()            # READ: the registers asked for do not exist
        # A WRITE value as its bytes come in; in a reply, the register or counter being sent,
        # LSB first (one shift register serves both)
        self.word = Signal(32)
        # How the command is refused, if it is (decided before it is answered)
        self.refusal = Signal()
        self.refusal_code = Signal(NakCode, init=NakCode.BAD_PAYLOAD)
        self.refusal_detail = Signal(16)

        # Reply being sent
        self.reply_type = Signal(8)
        self.reply_length = Signal(16)
        self.reply_final = Signal(16)       # index of the last payload byte
        # READ and STATUS: address of the register or field to be sent next (a READ reaches no
        # further than the last register, so it is narrow)
        self.next_pointer = Signal(range(max(len(REGISTERS) + 2, len(STATUS_FIELDS))))
        self.next_word = Signal(32)         # the register or counter at `next_pointer`
        self.is_status = Signal()           # the reply is a STATUS
        self.status_running = Signal()      # STATUS: `running` when it was asked for
        self.nak = Signal(Nak, init={"code": NakCode.BAD_CRC})
        self.link_pending = Signal()
        self.link_code = Signal(NakCode, init=NakCode.BAD_CRC)

        self.check = Signal()               # a WRITE value is complete: check it
        self.refusing = Signal()            # a NAK was decided in the previous cycle: count it
        self.accepting = Signal(init=1)     # packets are taken (in IDLE and PAYLOAD)

    def reply(self, type, length, final=None):
        """Statements that make the reply a ``type`` packet of ``length`` payload bytes
        (``final``: the index of the last, ``length - 1``, given without an adder when
        ``length`` is not a constant)."""
        return [self.reply_type.eq(type), self.is_status.eq(type == PacketType.STATUS),
                self.reply_length.eq(length),
                self.reply_final.eq(length - 1 if final is None else final)]

    def refuse(self, code, detail=0):
        """Statements that make the reply a NAK of the command, and count it."""
        return [
            self.nak.seq.eq(self.cmd_seq), self.nak.code.eq(code), self.nak.detail.eq(detail),
            *self.reply(PacketType.NAK, 4),
            self.refusing.eq(1),
        ]
