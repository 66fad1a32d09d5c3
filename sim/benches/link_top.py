"""The command side of :class:`fliss.hdl.top.FlissTop` without the UART, for fuzzing at one
byte per cycle: frame decoder, command processor, packet arbiter and frame encoder, wired as in
the top level."""

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from ...hdl import DEFAULT_CLOCK_HZ
from ...hdl.link.arbiter import PacketArbiter
from ...hdl.link.command import CommandProcessor
from ...hdl.link.framing import FrameDecoder, FrameEncoder
from ...hdl.protocol import LINK_FIELDS
from ...hdl.status import StatusCounters


__all__ = ["LinkTop"]


class LinkTop(wiring.Component):
    """Bytes in (``rx``), bytes out (``tx``): the link of the top level.

    Members
    -------
    rx : In(stream.Signature(8))
        Frame bytes from the host.
    tx : Out(stream.Signature(8))
        Frame bytes to the host.
    """

    rx: In(stream.Signature(8))
    tx: Out(stream.Signature(8))

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, baud=3_000_000):
        self.clock_hz, self.baud = clock_hz, baud
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.decoder = decoder = FrameDecoder()
        m.submodules.command = command = CommandProcessor(clock_hz=self.clock_hz, baud=self.baud)
        m.submodules.arbiter = arbiter = PacketArbiter(1)
        m.submodules.encoder = encoder = FrameEncoder()
        m.submodules.status = status = StatusCounters()
        wiring.connect(m, command.status, status.port)
        wiring.connect(m, wiring.flipped(self.rx), decoder.i)
        wiring.connect(m, decoder.o, command.packets)
        wiring.connect(m, command.replies, arbiter.i[0])
        wiring.connect(m, arbiter.o, encoder.i)
        wiring.connect(m, encoder.o, wiring.flipped(self.tx))
        m.d.comb += [
            command.link_error.eq(decoder.drop),
            command.link_error_code.eq(decoder.drop_reason),
            *(status.strobes[name].eq(decoder.tally[name]) for name in LINK_FIELDS),
            status.strobes.commands.eq(command.tally.commands),
            status.strobes.refused.eq(command.tally.refused),
        ]
        return m
