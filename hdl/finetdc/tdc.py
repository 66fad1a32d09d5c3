"""The fine TDC: delay line, encoder and calibration table with the coarse count since the TDC
start, giving the captures of the coarse TDC's layout."""

from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from ..event import ADDRESS_BITS, PULSE_BITS, TIMESTAMP_BITS
from ..tdc import Capture
from . import CODE_BITS, LINE_TAPS, LINES, LSB_SELECTS, TABLE_BITS, HitInput
from ..clock import cycle_units, elapsed_limit
from .encoder import Encoder
from .line import CARRY_BOX_FILE, DelayLine
from .source import OSCILLATOR_BOX_FILE, HitSource
from .table import CalibrationTable


__all__ = ["BLACK_BOX_FILES", "FineTdc"]


#: Declarations of the cells the fine TDC instantiates on an ECP5, as ``(file name, Verilog)``:
#: the carry cells' box (:data:`~.line.CARRY_BOX`) and the ECP5's oscillator ``OSCG``. Tools that
#: read its Verilog without a vendor library need them (``fliss generate --fine-tdc``).
BLACK_BOX_FILES = (CARRY_BOX_FILE, OSCILLATOR_BOX_FILE)


class FineTdc(wiring.Component):
    """Fine TDC: photon hits timestamped to a fraction of a clock cycle from the TDC start.

    A hit whose first non-zero sample of the delay lines (:class:`~.line.DelayLine`) is in their
    first stage in cycle ``c``, with raw code ``k`` (:class:`~.encoder.Encoder`: the ones count
    of all the lines' taps), arrived
    ``table[k]`` table units (:data:`~fliss.hdl.finetdc.UNIT_S`, 12.5 ps) before that sampling
    edge (:class:`~.table.CalibrationTable`). With ``s`` the cycle of the last ``tdc_start`` at
    or before ``c``, its timestamp is ``((c - s) * U - table[k]) >> (2 - lsb)``, ``U`` the clock
    period in table units: in LSBs of ``50 ps / 2**lsb``. A hit before the first start, more
    than :func:`~fliss.hdl.clock.elapsed_limit` cycles after the last, before its start
    (negative) or beyond 13 bits is flagged ``overflow`` (the event filter drops and counts it).
    With ``raw`` the timestamp is the raw code instead, never overflowing: the code-density
    histogram for the calibration. ``pulse`` is ``pulse_index - 1`` as it was in cycle ``c``;
    ``enable`` is sampled :data:`~fliss.hdl.finetdc.LATENCY` ``- 4`` cycles after ``c``. The
    capture is presented in cycle ``c +`` :data:`~fliss.hdl.finetdc.LATENCY`, in the layout of
    :class:`~fliss.hdl.tdc.CoarseTdc`'s, for the same :class:`~fliss.hdl.tdc.EventFilter`.

    At most one hit per clock cycle: the input must fall and the lines empty (a sample of all
    zeros) between two hits, so the dead time is the hit's width plus about two cycles.

    Parameters
    ----------
    clock_hz : int
        Clock frequency: its period must be a whole number of 12.5 ps units.
    taps : int
        Taps of each delay line.
    lines : int
        Delay lines; raw codes (0 to ``lines * taps``) must fit the calibration table's
        ``2**CODE_BITS`` entries.

    Members
    -------
    pin_hit : In(1)
        Photon hit, asynchronous, active high.
    laser_pad, aggressor_pad : In(1)
        The trigger outputs' pads read back (the internal loopback, :class:`~.source.HitSource`).
    input : In(HitInput)
        What drives the line.
    sampled : In(lines * taps)
        The lines' first stage, where there is no carry chain (:class:`~.line.DelayLine`).
    tdc_start, pulse_index, address, enable
        As in :class:`~fliss.hdl.tdc.CoarseTdc`.
    lsb : In(2)
        Timestamp LSB, ``50 ps / 2**lsb``, 0 to 2.
    raw : In(1)
        Raw codes as timestamps.
    table_seek, table_address, table_write, table_data : In
    table_read : Out(TABLE_BITS)
        The table's pointer, write and read back (:class:`~.table.CalibrationTable`).
    captures : Out(Capture)
        One capture per hit.
    """

    def __init__(self, *, clock_hz, taps=LINE_TAPS, lines=LINES):
        self.units = cycle_units(clock_hz)
        self.limit = elapsed_limit(clock_hz)
        if isinstance(taps, int) and isinstance(lines, int) and lines * taps >= 1 << CODE_BITS:
            raise ValueError(f"Raw codes up to {lines} lines of {taps} taps do not fit the "
                             f"calibration table's {1 << CODE_BITS} entries")
        self.taps = taps
        self.lines = lines
        super().__init__({
            "pin_hit":       In(1),
            "laser_pad":     In(1),
            "aggressor_pad": In(1),
            "input":         In(HitInput),
            "sampled":       In(lines * taps),
            "tdc_start":     In(1),
            "pulse_index":   In(PULSE_BITS),
            "address":       In(ADDRESS_BITS),
            "enable":        In(1),
            "lsb":           In(range(LSB_SELECTS)),
            "raw":           In(1),
            "table_seek":    In(1),
            "table_address": In(CODE_BITS),
            "table_write":   In(1),
            "table_data":    In(TABLE_BITS),
            "table_read":    Out(TABLE_BITS),
            "captures":      Out(Capture),
        })

    def elaborate(self, platform):
        m = Module()

        # Input, line, encoder, table
        m.submodules.source = source = HitSource()
        m.submodules.line = line = DelayLine(self.taps, self.lines)
        m.submodules.encoder = encoder = Encoder(self.lines * self.taps)
        m.submodules.table = table = CalibrationTable()
        m.d.comb += [
            source.pin.eq(self.pin_hit),
            source.laser.eq(self.laser_pad), source.aggressor.eq(self.aggressor_pad),
            source.select.eq(self.input),
            line.hit.eq(source.hit), line.sampled.eq(self.sampled),
            encoder.taps.eq(line.taps),
            table.code.eq(encoder.code),
            table.seek.eq(self.table_seek), table.seek_address.eq(self.table_address),
            table.write.eq(self.table_write), table.write_data.eq(self.table_data),
            self.table_read.eq(table.read_data),
        ]

        # TDC start and pulse index, delayed as much as the hit (second stage, ones count)
        start, pulse = self.tdc_start, self.pulse_index
        for stage in range(1 + encoder.stages):
            start_next = Signal(name=f"start_{stage + 1}")
            pulse_next = Signal(PULSE_BITS, name=f"pulse_{stage + 1}")
            m.d.sync += start_next.eq(start), pulse_next.eq(pulse)
            start, pulse = start_next, pulse_next

        # Whole cycles since the (delayed) start; limit + 1: past the limit or never started
        never = self.limit + 1
        elapsed = Signal(range(never + 1), init=never)
        now = Signal(range(never + 1))
        m.d.comb += now.eq(Mux(start, 0, elapsed))
        m.d.sync += elapsed.eq(Mux(now == never, never, now + 1))

        # While the table is read: the hit, its raw code, its cycle count in table units
        hit = Signal()
        code = Signal.like(encoder.code)
        base = Signal(range((never + 1) * self.units))
        late = Signal()
        event_pulse = Signal(PULSE_BITS)
        enabled = Signal()
        m.d.sync += hit.eq(encoder.hit)
        with m.If(encoder.hit):
            m.d.sync += [base.eq(now * self.units), late.eq(now == never), code.eq(encoder.code),
                         event_pulse.eq(pulse - 1), enabled.eq(self.enable)]

        # While the table's entry goes through its register
        looked = Signal()
        looked_base = Signal.like(base)
        looked_late = Signal()
        looked_code = Signal.like(code)
        looked_pulse = Signal(PULSE_BITS)
        looked_enabled = Signal()
        m.d.sync += looked.eq(hit)
        with m.If(hit):
            m.d.sync += [looked_base.eq(base), looked_late.eq(late), looked_code.eq(code),
                         looked_pulse.eq(event_pulse), looked_enabled.eq(enabled)]

        # The fine time subtracted
        ticks = Signal(range(-(1 << TABLE_BITS), (never + 1) * self.units))
        ticked = Signal()
        ticks_late = Signal()
        ticks_code = Signal.like(code)
        ticks_pulse = Signal(PULSE_BITS)
        ticks_enabled = Signal()
        m.d.sync += ticked.eq(looked)
        with m.If(looked):
            m.d.sync += [ticks.eq(looked_base - table.fine), ticks_late.eq(looked_late),
                         ticks_code.eq(looked_code), ticks_pulse.eq(looked_pulse),
                         ticks_enabled.eq(looked_enabled)]

        # Timestamp at the LSB, and the capture
        timestamp = Signal(len(ticks))
        m.d.comb += timestamp.eq(Mux(self.lsb == 2, ticks, Mux(self.lsb == 1, ticks[1:],
                                                                  ticks[2:])))
        captures = self.captures
        m.d.sync += captures.valid.eq(ticked)
        with m.If(ticked):
            m.d.sync += [
                captures.event.timestamp.eq(Mux(self.raw, ticks_code, timestamp)),
                captures.event.address.eq(self.address),
                captures.event.collision.eq(0),
                captures.event.pulse.eq(ticks_pulse),
                captures.overflow.eq(~self.raw & (ticks_late | (ticks < 0) |
                                                  (timestamp[TIMESTAMP_BITS:] != 0))),
                captures.enabled.eq(ticks_enabled),
            ]

        return m
