"""The link as one block: the UART, the frames, the command processor and the packet arbiter."""

from amaranth.hdl import Module
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from ..clock import DEFAULT_CLOCK_HZ, bit_cycles
from ..delay.settings import BANK_BITS
from ..protocol import DEFAULT_BAUD, LINK_FIELDS
from .arbiter import PacketArbiter
from .buffer import StreamBuffer
from .command import CommandProcessor, StatusSignature
from .framing import FrameDecoder, FrameEncoder, PacketBeat
from .uart import UartRx, UartTx


__all__ = ["UART_FIELDS", "COMMAND_FIELDS", "Link"]


#: The STATUS counters of the UART receiver's strobes ``framing_error`` and ``overrun``.
UART_FIELDS = ("uart_framing_errors", "uart_overruns")

#: The STATUS counters of the command processor's ``tally`` (same names).
COMMAND_FIELDS = ("commands", "refused")


class Link(wiring.Component):
    """The link of the top level: commands from the host answered, data packets sent to it.

    Frames from the host are decoded and checked (:class:`~.framing.FrameDecoder`) and their
    packets go to the command processor (:class:`~.command.CommandProcessor`), which answers
    each, and answers each frame the decoder drops with a NAK. Its replies, then the data
    packets of ``packets`` in priority order, are merged a packet at a time and numbered
    (:class:`~.arbiter.PacketArbiter`), then framed (:class:`~.framing.FrameEncoder`).

    Parameters
    ----------
    clock_hz : int
        Clock frequency in Hz.
    baud : int
        UART baud rate (refused at construction if the clock cannot make it within 2 %); without
        the UART, only the identity reports it.
    sources : int
        Data packet streams besides the replies, at least 0.
    maxima : dict or None
        Register maxima of the build (:class:`~.command.CommandProcessor` ``maxima``).
    bank_bits : int
        The histogram bank's address width (:class:`~.command.CommandProcessor` ``bank_bits``).
    uart : bool
        With the UART (:class:`~.uart.UartRx`, :class:`~.uart.UartTx`): ``rx`` and ``tx`` are
        the serial lines, 8N1, and a half-rate register slice sits between the frame encoder
        and the transmitter. Without it (to fuzz the link at a byte per cycle): byte streams.

    Members
    -------
    rx : In(1, init=1) or In(stream.Signature(8))
    tx : Out(1, init=1) or Out(stream.Signature(8))
        Serial lines to the host, or frame bytes from and to it.
    packets : In(stream.Signature(PacketBeat)).array(sources)
        Data packets, in priority order; their sequence numbers are filled in here.
    running : Out(1)
    update : Out(1)
        Acquisition started; settings changed while running (the command processor's).
    status : Out(StatusSignature)
        To the STATUS counters (:class:`~fliss.hdl.status.StatusCounters` ``port``).
    tally : Out(data.StructLayout)
        One strobe per STATUS counter of the link, named after it: :data:`UART_FIELDS` (with
        the UART), :data:`~fliss.hdl.protocol.LINK_FIELDS` and :data:`COMMAND_FIELDS`.

    Attributes
    ----------
    registers : :class:`~fliss.hdl.regfile.RegisterFile`
        The command processor's register file: the settings, by group.
    maxima : dict
        Register name -> its maximum in this build.
    """

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, baud=DEFAULT_BAUD, sources=0, maxima=None,
                 bank_bits=BANK_BITS, uart=True):
        if not isinstance(sources, int) or sources < 0:
            raise TypeError(f"Source count must be a non-negative integer, not {sources!r}")
        if not isinstance(uart, bool):
            raise TypeError(f"uart must be True or False, not {uart!r}")
        self.clock_hz, self.baud, self.sources, self.uart = clock_hz, baud, sources, uart
        if uart:
            bit_cycles(clock_hz, baud)
        self._command = CommandProcessor(clock_hz=clock_hz, baud=baud, maxima=maxima,
                                         bank_bits=bank_bits)
        self.registers = self._command.registers
        self.maxima = self._command.maxima
        fields = (UART_FIELDS if uart else ()) + LINK_FIELDS + COMMAND_FIELDS
        super().__init__({
            "rx":      In(1, init=1) if uart else In(stream.Signature(8)),
            "tx":      Out(1, init=1) if uart else Out(stream.Signature(8)),
            "packets": In(stream.Signature(PacketBeat)).array(sources),
            "running": Out(1),
            "update":  Out(1),
            "status":  Out(StatusSignature),
            "tally":   Out(data.StructLayout({name: 1 for name in fields})),
        })

    def elaborate(self, platform):
        m = Module()

        # Commands in: checked frames to the command processor, dropped ones reported to it
        m.submodules.decoder = decoder = FrameDecoder()
        m.submodules.command = command = self._command
        wiring.connect(m, decoder.o, command.packets)
        m.d.comb += [
            command.link_error.eq(decoder.drop),
            command.link_error_code.eq(decoder.drop_reason),
            self.running.eq(command.running),
            self.update.eq(command.update),
        ]
        wiring.connect(m, command.status, wiring.flipped(self.status))

        # Packets out: the replies first, then the data packets, numbered and framed
        m.submodules.arbiter = arbiter = PacketArbiter(1 + self.sources)
        m.submodules.encoder = encoder = FrameEncoder()
        wiring.connect(m, command.replies, arbiter.i[0])
        for source, port in zip(self.packets, arbiter.i[1:]):
            wiring.connect(m, wiring.flipped(source), port)
        wiring.connect(m, arbiter.o, encoder.i)

        # Counter strobes, by STATUS counter
        m.d.comb += [
            *(self.tally[name].eq(decoder.tally[name]) for name in LINK_FIELDS),
            *(self.tally[name].eq(command.tally[name]) for name in COMMAND_FIELDS),
        ]

        # Bytes: through the UART, or straight from and to the ports
        if self.uart:
            m.submodules.uart_rx = uart_rx = UartRx(clock_hz=self.clock_hz, baud=self.baud)
            m.submodules.uart_tx = uart_tx = UartTx(clock_hz=self.clock_hz, baud=self.baud)
            # A register slice between the encoder's run buffer (block RAM, slow output) and
            # the transmitter, for timing; half rate is plenty for a UART and puts no
            # multiplexer after the RAM.
            m.submodules.tx_buffer = tx_buffer = StreamBuffer(8, full_rate=False)
            # And one between the receiver and the frame decoder: the receiver sits by its
            # pin, the decoder by the command processor, and the byte's write enable (the
            # receiver's last vote) would cross the chip after four levels of logic.
            m.submodules.rx_buffer = rx_buffer = StreamBuffer(8, full_rate=False)
            wiring.connect(m, uart_rx.o, rx_buffer.i)
            wiring.connect(m, rx_buffer.o, decoder.i)
            wiring.connect(m, encoder.o, tx_buffer.i)
            wiring.connect(m, tx_buffer.o, uart_tx.i)
            m.d.comb += [
                uart_rx.rx.eq(self.rx),
                self.tx.eq(uart_tx.tx),
                self.tally.uart_framing_errors.eq(uart_rx.framing_error),
                self.tally.uart_overruns.eq(uart_rx.overrun),
            ]
        else:
            wiring.connect(m, wiring.flipped(self.rx), decoder.i)
            wiring.connect(m, encoder.o, wiring.flipped(self.tx))

        return m
