"""UART transmitter and receiver, 8N1, with a fractional bit time.

A bit lasts ``c = clock_hz / baud`` clock cycles, kept as a fixed-point number with
:data:`FRACTION_BITS` fraction bits. Bit boundaries are placed at whole cycles by accumulating
``c`` from the start of each character, so bit edges jitter by less than one cycle but do not
drift: 12 Mbaud from 80 MHz (``c = 6.67``) is exact on average. :func:`bit_cycles` validates the
parameters; :mod:`fliss.sim.models.uart` is the bit-level model of both blocks.
"""

from amaranth.hdl import C, Cat, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.wiring import In, Out

from ..clock import DEFAULT_CLOCK_HZ, FRACTION_BITS, bit_cycles
from ..protocol import COUNTER_BITS


__all__ = ["DATA_BITS", "CHARACTER_BITS", "UartTx", "UartRx"]


#: Data bits per character (8N1: one start bit, 8 data bits LSB first, no parity, one stop bit).
DATA_BITS = 8

#: Bit times per character on the line: start, data, stop.
CHARACTER_BITS = 1 + DATA_BITS + 1


class _Uart(wiring.Component):
    # What both ends share: the bit time, from the clock and the baud rate checked here.
    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, baud=115_200):
        self.bit_cycles = bit_cycles(clock_hz, baud)
        self.clock_hz = clock_hz
        self.baud = baud
        super().__init__()


class UartTx(_Uart):
    """UART transmitter, 8N1.

    Sends each byte taken from ``i``: a start bit (0), 8 data bits least significant first, a
    stop bit (1). A character starts in the cycle after its transfer; ``i.ready`` is high in the
    last cycle of a stop bit, so a byte that is waiting follows without an idle cycle.

    Bit timing: in a burst of characters sent back to back, bit ``k`` of the burst (``k = 0`` the
    first start bit, 10 bits per character) begins ``(k * C + 2**(F-1)) >> F`` cycles after the
    burst, ``C`` being :func:`bit_cycles` and ``F`` :data:`FRACTION_BITS`: the fraction of a cycle
    left over at the end of a character carries into the next one, so a long burst runs at the
    exact baud rate.

    Parameters
    ----------
    clock_hz : int
        Clock frequency in Hz.
    baud : int
        Baud rate.

    Members
    -------
    i : In(stream.Signature(8))
        Bytes to send.
    tx : Out(1, init=1)
        Serial output, straight from a flip-flop; high when idle.
    busy : Out(1)
        A character is being sent.
    """

    i:    In(stream.Signature(DATA_BITS))
    tx:   Out(1, init=1)
    busy: Out(1)

    def elaborate(self, platform):
        m = Module()

        step = self.bit_cycles
        half = 1 << (FRACTION_BITS - 1)
        fraction = (1 << FRACTION_BITS) - 1

        # Bit timing: `remaining` counts down the cycles of the current bit; `frac` is the
        # fraction of a cycle by which the bit's ideal start precedes its actual start (plus
        # half a cycle, for rounding). A bit starting with fraction `frac` lasts
        # `(frac + step) >> F` cycles, and the next one starts with `(frac + step) % 2**F`.
        remaining = Signal(range(((step + fraction) >> FRACTION_BITS) + 1))
        frac = Signal(FRACTION_BITS)
        bit = Signal(range(CHARACTER_BITS))
        shreg = Signal(DATA_BITS + 1)
        last_cycle = Signal()       # last cycle of a stop bit, registered

        def start_bit(start_frac):
            total = start_frac + step
            m.d.sync += [
                remaining.eq((total >> FRACTION_BITS) - 1),
                frac.eq(total[:FRACTION_BITS]),
            ]

        # Next character; back to back, the fraction of a cycle left over carries on
        m.d.comb += self.i.ready.eq(~self.busy | last_cycle)
        m.d.sync += last_cycle.eq(0)
        with m.If(self.i.valid & self.i.ready):
            m.d.sync += [
                self.busy.eq(1),
                self.tx.eq(0),
                shreg.eq(Cat(self.i.payload, C(1, 1))),
                bit.eq(0),
            ]
            start_bit(Mux(last_cycle, frac, half))
        # Shift out
        with m.Elif(last_cycle):
            m.d.sync += [
                self.busy.eq(0),
                self.tx.eq(1),
            ]
        with m.Elif(self.busy):
            m.d.sync += remaining.eq(remaining - 1)
            with m.If((bit == CHARACTER_BITS - 1) & (remaining == 1)):
                m.d.sync += last_cycle.eq(1)
            with m.If(remaining == 0):
                m.d.sync += [
                    self.tx.eq(shreg[0]),
                    shreg.eq(shreg >> 1),
                    bit.eq(bit + 1),
                ]
                start_bit(frac)

        return m


class UartRx(_Uart):
    """UART receiver, 8N1, with a majority vote and framing error detection.

    The ``rx`` input passes through a two flip-flop synchroniser (high after reset). A low level
    in the idle state starts a character; bit ``k`` (``k = 0`` the start bit, ``k = 9`` the stop
    bit) is the majority of three samples centred ``(k * C + C // 2) >> F`` cycles after that,
    ``C`` being :func:`bit_cycles` and ``F`` :data:`FRACTION_BITS`. A start bit that votes high is
    a glitch and is ignored. After the stop bit's vote the receiver is idle again, half a bit
    early; if the line is already low in that cycle, the next character starts there and then.
    In a sweep of the model from 115 200 baud to 20 Mbaud at 80 MHz the receiver accepts a sender
    whose baud rate is 2.5 % off either way (at 12 Mbaud about -4.5 % to +4 %).

    A stop bit that votes low is a framing error: the byte is dropped, ``framing_errors`` counts
    it, and the receiver waits for the line to go high before it looks for a start bit, so a
    break (line held low) counts once. A byte received while the previous one is still waiting
    on ``o`` is dropped and counted in ``overruns``.

    Parameters
    ----------
    clock_hz : int
        Clock frequency in Hz.
    baud : int
        Baud rate.

    Members
    -------
    rx : In(1, init=1)
        Serial input, asynchronous.
    o : Out(stream.Signature(8))
        Bytes received with a good stop bit.
    framing_error : Out(1)
        Strobe: a character with a bad stop bit was dropped.
    overrun : Out(1)
        Strobe: a byte was dropped because ``o`` was not ready.
    framing_errors : Out(32)
        Characters dropped for a bad stop bit (wraps around).
    overruns : Out(32)
        Bytes dropped because ``o`` was not ready (wraps around).
    """

    rx:             In(1, init=1)
    o:              Out(stream.Signature(DATA_BITS))
    framing_error:  Out(1)
    overrun:        Out(1)
    framing_errors: Out(COUNTER_BITS)
    overruns:       Out(COUNTER_BITS)

    def elaborate(self, platform):
        m = Module()

        step = self.bit_cycles
        last_vote = (CHARACTER_BITS - 1) * step + step // 2

        # Input synchroniser and majority vote over this sample and the two before it
        rx = Signal(init=1)
        m.submodules.sync = FFSynchronizer(self.rx, rx, init=1)
        rx_1 = Signal(init=1)
        rx_2 = Signal(init=1)
        m.d.sync += [rx_1.eq(rx), rx_2.eq(rx_1)]
        vote = Signal()
        m.d.comb += vote.eq((rx & rx_1) | (rx & rx_2) | (rx_1 & rx_2))

        # Bit timing: a vote is taken when `cycle` (from the start edge) reaches `edge` + 1,
        # kept in `target` (so that the sum is not on the path to the vote's decisions)
        # (`edge` is read up to the stop bit's vote, at `last_vote`; the value written at that
        # vote, a bit later, is never read and may wrap)
        cycle = Signal(range((last_vote >> FRACTION_BITS) + 2))
        edge = Signal(range(last_vote + 1))
        target = Signal.like(cycle)
        bit = Signal(range(CHARACTER_BITS))
        shreg = Signal(DATA_BITS)
        sample = Signal()
        m.d.comb += sample.eq(cycle == target)
        first_target = ((step // 2) >> FRACTION_BITS) + 1

        # Output stream: a new byte waits until the previous one is taken
        with m.If(self.o.ready):
            m.d.sync += self.o.valid.eq(0)

        m.d.sync += self.framing_error.eq(0), self.overrun.eq(0)
        with m.FSM():
            with m.State("IDLE"):
                with m.If(~rx):
                    m.d.sync += [
                        cycle.eq(1),
                        edge.eq(step // 2),
                        target.eq(first_target),
                        bit.eq(0),
                    ]
                    m.next = "RECEIVE"

            with m.State("RECEIVE"):
                m.d.sync += cycle.eq(cycle + 1)
                with m.If(sample):
                    m.d.sync += [
                        edge.eq(edge + step),
                        target.eq(((edge + step) >> FRACTION_BITS) + 1),
                        bit.eq(bit + 1),
                    ]
                    with m.If(bit == 0):
                        with m.If(vote):
                            m.next = "IDLE"     # glitch, not a start bit
                    with m.Elif(bit == CHARACTER_BITS - 1):
                        with m.If(vote):
                            with m.If(self.o.valid & ~self.o.ready):
                                m.d.sync += [
                                    self.overruns.eq(self.overruns + 1),
                                    self.overrun.eq(1),
                                ]
                            with m.Else():
                                m.d.sync += [
                                    self.o.payload.eq(shreg),
                                    self.o.valid.eq(1),
                                ]
                            with m.If(~rx):
                                # the next start bit began in this very cycle: a faster
                                # sender loses no cycle of margin to the idle state
                                m.d.sync += [
                                    cycle.eq(1),
                                    edge.eq(step // 2),
                                    target.eq(first_target),
                                    bit.eq(0),
                                ]
                            with m.Else():
                                m.next = "IDLE"
                        with m.Else():
                            m.d.sync += [
                                self.framing_error.eq(1),
                                self.framing_errors.eq(self.framing_errors + 1),
                            ]
                            m.next = "BREAK"
                    with m.Else():
                        m.d.sync += shreg.eq(Cat(shreg[1:], vote))

            with m.State("BREAK"):
                with m.If(rx):
                    m.next = "IDLE"

        return m
