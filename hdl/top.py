from amaranth.hdl import Module, Mux, Signal
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out

from .clock import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, bit_cycles, cycle_units, period_cycles
from .delay.aggressor import Aggressor
from .delay.core import DelayCore
from .depth.engine import DepthEngine
from .event import TIMESTAMP_BITS, ADDRESS_BITS
from .histogram.engine import Histogram, RAM_KINDS
from .histogram.layout import ReadoutSplit
from .delay.keyed import Keying
from .link.link import Link
from .packets.events import EventPacketizer
from .packets.histogram import HistogramPacketizer
from .packets.histogram_full import FullHistogramPacketizer
from .protocol import DEFAULT_BAUD
from .rawfifo import RawFifo
from .registers import (VICTIM, AGGRESSOR, AGGRESSOR_DELAY, KEYING, DEPTH, FINE_TDC,
                        AcquisitionMode, TdcSource)
from .delay.modes import mode_maximum
from .delay.settings import (BANK_BITS, MAX_BANK_BITS, MIN_BANK_BITS, PERIOD_WIDTH,
                             PULSE_WIDTH_WIDTH, check_widths)
from .spram import SPRAM_DEPTH
from .status import StatusCounters
from .tdc import EventFilter, TdcInterface, CoarseTdc
from .finetdc import HitInput
from .finetdc.tdc import FineTdc


__all__ = ["DEFAULT_BAUD", "SPRAM_BANK_BITS", "SMALL", "FlissTop"]


#: ``bank_bits`` of single-port banks on an iCE40 UltraPlus: one ``SB_SPRAM256KA`` per bank.
SPRAM_BANK_BITS = SPRAM_DEPTH.bit_length() - 1


#: Options of :class:`FlissTop` for the smallest build, which fits an iCE40UP5K (the
#: iCEBreaker's FPGA): histograms only, in single-port RAM (one SPRAM per bank: 16384 bins,
#: ``bank_bits`` 14), of one pixel selected by address (``max_pixel_bits`` 0: the per-pixel
#: logic does not fit); no aggressor emitter; no keyed delay source; no depth engine; full
#: histogram chunks only; periods up to 2**24 - 1 cycles (0.47 s at 36 MHz, the iCEBreaker's
#: clock) and pulses up to 255 cycles.
SMALL = dict(histogram_ram="single", bank_bits=SPRAM_BANK_BITS, max_pixel_bits=0,
             aggressor=False, raw_events=False, keyed=False, depth=False, period_width=24,
             pulse_width_width=8, compact_readout=False)


def _switch_frames(m, readout, first, second, to_second):
    """Send each frame of ``readout`` (a stream of bins, ``last`` on a frame's final bin) whole
    to ``first`` or ``second``: to ``second`` when ``to_second`` is high at its first bin."""
    in_frame = Signal()
    was_second = Signal()
    second_now = Mux(in_frame, was_second, to_second)
    with m.If(readout.valid & readout.ready):
        m.d.sync += [in_frame.eq(~readout.p.last), was_second.eq(second_now)]
    for reader, selected in ((first, ~second_now), (second, second_now)):
        m.d.comb += [reader.valid.eq(readout.valid & selected),
                     reader.payload.eq(readout.payload)]
    m.d.comb += readout.ready.eq(Mux(second_now, second.ready, first.ready))


class FlissTop(wiring.Component):
    """FLISS top level: the whole instrument behind a UART.

    A host drives it with the packets of :mod:`fliss.hdl.protocol` over ``uart_rx`` and
    ``uart_tx``: it reads and writes the registers of :mod:`fliss.hdl.registers`, starts and
    stops acquisition, and receives histograms or raw events and status.

    Parameters
    ----------
    clock_hz : int
        Clock frequency in Hz.
    baud : int
        UART baud rate; refused at construction if the clock cannot make it within 2 %.
    raw_depth : int
        Depth of the raw event FIFO, in events.
    histogram_ram : str
        Storage of the histogram banks (:class:`~fliss.hdl.histogram.engine.Histogram` ``ram``):
        ``"dual"`` (block RAM) or ``"single"`` (single-port RAM: the SPRAM of an iCE40UP5K).
    bank_bits : int or None
        Each histogram bank holds ``2**bank_bits`` bins, from 13 to 19 (``None``: 16 with
        ``"dual"``, 64 pixels of 1024 bins; 14 with ``"single"``, one SPRAM). The register file
        refuses a pixel split that does not fit, and IDENTITY reports it.
    max_pixel_bits : int
        Largest ``pixel_bits``, 0 to 6 (``Histogram`` ``max_pixel_bits``); below 6 the register
        file refuses larger values as out of range (0: one pixel, selected by ``first_pixel``).
    aggressor_delays : bool
        Give the aggressor emitter a delay source of its own. Without it (a smaller build, for
        the iCE40UP5K), the aggressor fires on its nominal schedule only, and a write of
        ``aggressor_delay_mode`` other than 0 (off) is refused as out of range.
    aggressor : bool
        Build the aggressor emitter. Without it, ``aggressor_laser`` stays low, and a write of
        ``aggressor`` other than 0 (off) is refused as out of range.
    period_width, pulse_width_width : int
        Widths of the victim's ``period`` and ``pulse_width`` settings (and the aggressor's), in
        bits: 32 and 16 by default; narrower ones make a smaller build, whose register file
        refuses larger values as out of range (see :func:`~fliss.hdl.delay.scheduler.check_widths`).
    raw_events : bool
        Build raw-event mode (the event FIFO and the EVENTS packetizer). Without it, a write of
        ``acquisition`` other than 0 (histograms) is refused as out of range.
    keyed : bool
        Build the victim's keyed delay source (Trivium, :class:`~fliss.hdl.delay.keyed.KeyedStream`).
        Without it, a write of ``delay_mode`` 3 (keyed), or of a key or IV other than 0, is
        refused as out of range.
    depth : bool
        Build the depth engine (:class:`~fliss.hdl.depth.engine.DepthEngine`), which turns each
        histogram into a DEPTH packet in acquisition mode 2 (depth). Without it, a write of
        ``acquisition`` 2 is refused as out of range. It needs ``raw_events`` (the register
        file refuses modes above a maximum, so it cannot refuse mode 1 alone).

    compact_readout : bool
        Build the histogram packetizer that sends compact chunks where shorter
        (:class:`~fliss.hdl.packets.histogram.HistogramPacketizer`). Without it (some 590
        LUTs and two block RAMs less on an iCE40), every histogram goes out in full HISTOGRAM
        chunks (:class:`~fliss.hdl.packets.histogram_full.FullHistogramPacketizer`), whatever
        ``full_readout`` says; hosts read both forms alike.
    fine_tdc : bool
        Build the fine TDC (:class:`~fliss.hdl.finetdc.tdc.FineTdc`: delay lines of ECP5 carry
        cells on ``photon_hit``, ``tdc_source`` 2 and 3), with its internal loopback (the
        ports ``laser_pad`` and, with the aggressor, ``aggressor_laser_pad``: ``tdc_input`` 2
        and 3); the clock period must be a whole number of 12.5 ps. Without it (the default:
        its two lines alone are 402 carry cells, 1600 flip-flops and 800 LUTs, besides the ones
        count and a block RAM; only the ECP5 has the chain), a write of ``tdc_source`` above 1, or of the fine TDC's registers other than 0,
        is refused as out of range; without the aggressor, a write of ``tdc_input`` 3.

    Smaller builds answer every command as the full one does, except for the refusals above:
    the host finds what is missing from a NAK ``OUT_OF_RANGE`` with the register's address.

    Members
    -------
    uart_rx : In(1)
    uart_tx : Out(1)
        Serial link to the host, 8N1.
    laser : Out(1)
    tdc_start : Out(1)
        Victim laser trigger and TDC start (same cycle).
    aggressor_laser : Out(1)
        Aggressor laser trigger.
    sensor_valid : In(1)
    sensor_timestamp : In(13)
    sensor_address : In(6)
    sensor_collision : In(1)
        The sensor's TDC output bus, captured on ``sensor_valid``.
    photon_hit : In(1)
        Photon detector pulse for the built-in coarse TDC and the fine TDC.
    running : Out(1)
        Acquisition running (for an LED).
    laser_pad, aggressor_laser_pad : In(1)
        With the fine TDC (the second with the aggressor too): the pads of ``laser`` and
        ``aggressor_laser`` read back, for its internal loopback (a board makes the pad
        bidirectional, its output always enabled: :class:`~fliss.boards.BoardTop`).
    """

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, baud=DEFAULT_BAUD, raw_depth=512,
                 histogram_ram="dual", bank_bits=None, max_pixel_bits=ADDRESS_BITS,
                 aggressor_delays=True, aggressor=True, raw_events=True, keyed=True, depth=True,
                 period_width=PERIOD_WIDTH, pulse_width_width=PULSE_WIDTH_WIDTH,
                 compact_readout=True, fine_tdc=False):
        self.clock_hz = clock_hz
        self.baud = baud
        self.raw_depth = raw_depth
        self.histogram_ram = histogram_ram
        # Validate the parameters now rather than at elaboration.
        if histogram_ram not in RAM_KINDS:
            raise ValueError(f"Histogram RAM must be one of {', '.join(map(repr, RAM_KINDS))}, "
                             f"not {histogram_ram!r}")
        if bank_bits is None:
            bank_bits = BANK_BITS if histogram_ram == "dual" else SPRAM_BANK_BITS
        if not isinstance(bank_bits, int) or not MIN_BANK_BITS <= bank_bits <= MAX_BANK_BITS:
            raise ValueError(f"Histogram bank address width must be an integer from "
                             f"{MIN_BANK_BITS} to {MAX_BANK_BITS} bits, not {bank_bits!r}")
        self.bank_bits = bank_bits
        if not isinstance(max_pixel_bits, int) or not 0 <= max_pixel_bits <= ADDRESS_BITS:
            raise ValueError(f"Most pixel bits must be an integer from 0 to {ADDRESS_BITS}, "
                             f"not {max_pixel_bits!r}")
        self.max_pixel_bits = max_pixel_bits
        for name, value in (("aggressor_delays", aggressor_delays), ("aggressor", aggressor),
                            ("raw_events", raw_events), ("keyed", keyed), ("depth", depth),
                            ("compact_readout", compact_readout), ("fine_tdc", fine_tdc)):
            if not isinstance(value, bool):
                raise TypeError(f"{name} must be True or False, not {value!r}")
        if depth and not raw_events:
            # (a register maximum cannot refuse acquisition mode 1 and accept mode 2)
            raise ValueError("A build with the depth engine must have raw events too: "
                             "depth=True needs raw_events=True")
        self.aggressor = aggressor
        self.aggressor_delays = aggressor_delays and aggressor
        self.raw_events = raw_events
        self.keyed = keyed
        self.compact_readout = compact_readout
        self.depth = depth
        if fine_tdc:
            cycle_units(clock_hz)
        self.fine_tdc = fine_tdc
        check_widths(period_width, pulse_width_width)
        self.period_width = period_width
        self.pulse_width_width = pulse_width_width
        period_cycles(clock_hz, DEFAULT_PRF_HZ)
        bit_cycles(clock_hz, baud)
        super().__init__(self._ports())

    def _ports(self):
        # The signature: the fixed ports, and the pads read back for the fine TDC's internal
        # loopback
        ports = {
            "uart_rx":          In(1, init=1),
            "uart_tx":          Out(1, init=1),
            "laser":            Out(1),
            "tdc_start":        Out(1),
            "aggressor_laser":  Out(1),
            "sensor_valid":     In(1),
            "sensor_timestamp": In(TIMESTAMP_BITS),
            "sensor_address":   In(ADDRESS_BITS),
            "sensor_collision": In(1),
            "photon_hit":       In(1),
            "running":          Out(1),
        }
        if self.fine_tdc:
            ports["laser_pad"] = In(1)
            if self.aggressor:
                ports["aggressor_laser_pad"] = In(1)
        return ports

    def register_maxima(self):
        """Register maxima lowered for this build (see :class:`~.link.command.CommandProcessor`).

        Asking a top level for its maxima uses it: one made for that alone (by the model board,
        a test) draws no ``UnusedElaboratable`` warning when it is collected, which would
        otherwise come at any later time, in the middle of some other output."""
        self._MustUse__used = True      # (Amaranth's own mark of an elaboratable put to use)
        maxima = {}
        for group in (VICTIM, AGGRESSOR_DELAY):
            if self.period_width < PERIOD_WIDTH:
                maxima[group.register("period").name] = (1 << self.period_width) - 1
            if self.pulse_width_width < PULSE_WIDTH_WIDTH:
                maxima[group.register("pulse_width").name] = (1 << self.pulse_width_width) - 1
        if not self.aggressor:
            # Its registers stay, for hosts that write a range of registers across them, but
            # only as wide as their reset values need.
            for register in AGGRESSOR.members + AGGRESSOR_DELAY.members:
                least = max(register.minimum, register.reset_value(self.clock_hz))
                maxima[register.name] = min(register.maximum, (1 << least.bit_length()) - 1)
            maxima[AGGRESSOR.register("enable").name] = 0
        if not self.aggressor_delays:
            maxima[AGGRESSOR_DELAY.register("mode").name] = 0
        if not self.depth:      # (and so, without raw events, no depth either)
            maxima["acquisition"] = AcquisitionMode.RAW.value
            # its settings stay, as wide as their reset values need (as the aggressor's)
            for register in DEPTH.members:
                least = max(register.minimum, register.reset_value(self.clock_hz))
                maxima[register.name] = min(register.maximum, (1 << least.bit_length()) - 1)
        if not self.raw_events:
            maxima["acquisition"] = AcquisitionMode.HISTOGRAM.value
        if self.max_pixel_bits < ADDRESS_BITS:
            maxima["pixel_bits"] = self.max_pixel_bits
        if not self.fine_tdc:
            maxima["tdc_source"] = TdcSource.COARSE.value
            for register in FINE_TDC.members:
                maxima[register.name] = register.reset_value(self.clock_hz)
        elif not self.aggressor:
            maxima[FINE_TDC.register("input").name] = HitInput.LASER.value
        if not self.keyed:
            maxima[VICTIM.register("mode").name] = mode_maximum(keyed=False)
            for register in KEYING.members:
                maxima[register.name] = 0
        return maxima

    def elaborate(self, platform):
        m = Module()

        # Link: the UART, commands and the register file; the data packets leave through it
        # after the replies, in this order
        kinds = ["histogram"] + ["events"] * self.raw_events + ["depth"] * self.depth
        m.submodules.link = link = Link(
            clock_hz=self.clock_hz, baud=self.baud, sources=len(kinds),
            maxima=self.register_maxima(), bank_bits=self.bank_bits)
        sources = dict(zip(kinds, link.packets))
        registers = link.registers
        acquisition = registers.acquisition
        running = link.running
        m.d.comb += [
            link.rx.eq(self.uart_rx),
            self.uart_tx.eq(link.tx),
            self.running.eq(running),
        ]

        # Victim: delay source, scheduler, laser trigger and TDC start
        m.submodules.core = core = DelayCore(clock_hz=self.clock_hz,
                                             period_width=self.period_width,
                                             pulse_width_width=self.pulse_width_width,
                                             keyed=self.keyed)
        m.d.comb += [
            core.enable.eq(running),
            core.update.eq(link.update),
            core.settings.eq(registers.victim),
            self.laser.eq(core.laser),
            self.tdc_start.eq(core.tdc_start),
        ]
        if self.keyed:
            m.d.comb += [
                *(core.keying[name].eq(registers.keying[name])
                  for name, _ in data.Layout.cast(Keying)),
                core.rekey.eq(registers.rekey),
                registers.iv.eq(core.iv),
            ]

        # Aggressor
        if self.aggressor:
            m.submodules.aggressor = aggressor = Aggressor(
                delay_source=self.aggressor_delays, period_width=self.period_width,
                pulse_width_width=self.pulse_width_width)
            m.d.comb += [
                aggressor.enable.eq(running),
                aggressor.update.eq(link.update),
                aggressor.emitter.eq(registers.aggressor),
                aggressor.settings.eq(registers.aggressor_delay),
                self.aggressor_laser.eq(aggressor.laser),
            ]

        # Events: the sensor bus or the built-in coarse TDC, tagged with the laser cycle index;
        # one event filter (gate, counters) serves the selected one.
        m.submodules.sensor = sensor = TdcInterface(filtered=False)
        m.submodules.coarse = coarse = CoarseTdc(filtered=False)
        m.submodules.event_filter = event_filter = EventFilter()
        coarse_selected = acquisition.tdc_source == TdcSource.COARSE
        for tdc in (sensor, coarse):
            m.d.comb += tdc.enable.eq(running)
            if self.raw_events:     # (histograms need no pulse index: leave it out)
                m.d.comb += tdc.pulse_index.eq(core.pulse_index)
        m.d.comb += [
            sensor.pin_valid.eq(self.sensor_valid),
            sensor.pin_timestamp.eq(self.sensor_timestamp),
            sensor.pin_address.eq(self.sensor_address),
            sensor.pin_collision.eq(self.sensor_collision),
            coarse.pin_hit.eq(self.photon_hit),
            coarse.tdc_start.eq(core.tdc_start),
            event_filter.gate.eq(registers.gate),
            event_filter.events.ready.eq(1),
        ]
        captures = Mux(coarse_selected, coarse.captures, sensor.captures)
        if self.fine_tdc:
            captures = self._fine_tdc(m, registers, core, link, captures)
        m.d.comb += event_filter.captures.eq(captures)
        events = event_filter.events.payload
        events_valid = event_filter.events.valid

        # Histogram mode
        raw_mode = acquisition.mode == AcquisitionMode.RAW
        m.submodules.histogram = histogram = Histogram(bank_bits=self.bank_bits,
                                                       ram=self.histogram_ram,
                                                       max_pixel_bits=self.max_pixel_bits)
        packetizer = HistogramPacketizer if self.compact_readout else FullHistogramPacketizer
        m.submodules.histogram_packets = histogram_packets = \
            packetizer(index_bits=self.bank_bits)
        m.d.comb += [
            histogram.enable.eq(running & ~raw_mode),
            # (field by field: a build's maxima may narrow some)
            *(histogram.settings[name].eq(registers.histogram[name])
              for name, _ in data.Layout.cast(registers.histogram.shape())),
            histogram.events.valid.eq(events_valid & ~raw_mode),
            histogram.events.payload.eq(events),
            histogram_packets.full_readout.eq(registers.histogram.full_readout),
        ]
        wiring.connect(m, histogram_packets.packets, sources["histogram"])
        readers = [histogram_packets]

        # Depth mode: the readout goes to the depth engine instead, a frame at a time (the
        # mode is taken at a frame's first bin)
        if self.depth:
            m.submodules.depth = depth = DepthEngine(index_bits=len(histogram.readout.p.index))
            readers.append(depth)
            _switch_frames(m, histogram.readout, histogram_packets.readout, depth.readout,
                           acquisition.mode == AcquisitionMode.DEPTH)
            m.d.comb += depth.settings.eq(registers.depth)
            wiring.connect(m, depth.packets, sources["depth"])
        else:
            wiring.connect(m, histogram.readout, histogram_packets.readout)

        # The split of the frame being read out, to each block that reads it
        for reader in readers:
            m.d.comb += [getattr(reader, name).eq(histogram.readout_split[name])
                         for name, _ in data.Layout.cast(ReadoutSplit)]

        # Raw mode
        if self.raw_events:
            m.submodules.raw_fifo = raw_fifo = RawFifo(depth=self.raw_depth)
            m.submodules.event_packets = event_packets = EventPacketizer()
            m.d.comb += [
                raw_fifo.events.valid.eq(events_valid & raw_mode),
                raw_fifo.events.payload.eq(events),
                event_packets.level.eq(raw_fifo.level),
                event_packets.flush.eq(~running),
            ]
            wiring.connect(m, raw_fifo.output, event_packets.events)
            wiring.connect(m, event_packets.packets, sources["events"])

        # Status counters: each block's tally strobes, by the STATUS counter each one counts
        m.submodules.status = status = StatusCounters()
        wiring.connect(m, link.status, status.port)
        m.d.comb += [
            status.pulses.eq(core.pulse_index),
            *status.count(link.tally),
            *status.count(event_filter.tally, accepted="events"),
            *status.count(histogram.tally, dropped="dropped_histogram", dropped_busy=None,
                          overflow="histogram_overflow"),
        ]
        if self.raw_events:
            m.d.comb += status.count(raw_fifo.tally, accepted=None, dropped="dropped_fifo")
        if self.keyed:
            m.d.comb += status.ivs_used_up.eq(core.spent)

        return m

    def _fine_tdc(self, m, registers, core, link, captures):
        # The fine TDC on the photon pin (or the oscillator, or a trigger's pad: `tdc_input`);
        # its captures when `tdc_source` selects it
        m.submodules.fine = fine = FineTdc(clock_hz=self.clock_hz)
        source = registers.acquisition.tdc_source
        settings = registers.fine_tdc
        m.d.comb += [
            fine.pin_hit.eq(self.photon_hit),
            fine.laser_pad.eq(self.laser_pad),
            fine.input.eq(settings.input),
            fine.tdc_start.eq(core.tdc_start),
            fine.pulse_index.eq(core.pulse_index),
            fine.enable.eq(link.running),
            fine.lsb.eq(settings.lsb),
            fine.raw.eq(source == TdcSource.FINE_RAW),
            fine.table_seek.eq(registers.table_seek),
            fine.table_address.eq(settings.table_address),
            fine.table_write.eq(registers.table_write),
            fine.table_data.eq(settings.table_data),
            registers.table_read.eq(fine.table_read),
        ]
        if self.aggressor:
            m.d.comb += fine.aggressor_pad.eq(self.aggressor_laser_pad)
        return Mux(source[1], fine.captures, captures)
