"""The link of :class:`fliss.hdl.top.FlissTop` without the UART, for fuzzing at one byte per
cycle: :class:`fliss.hdl.link.link.Link` with byte streams for its serial lines and no data
packets, the STATUS counters of its strobes, and the fine TDC's calibration table (the register
file reads ``table_data`` from it, as in a build with the fine TDC)."""

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.finetdc.table import CalibrationTable, serve_registers
from ...hdl.link.link import Link
from ...hdl.protocol import DEFAULT_BAUD
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

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, baud=DEFAULT_BAUD):
        self.clock_hz, self.baud = clock_hz, baud
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.link = link = Link(clock_hz=self.clock_hz, baud=self.baud, uart=False)
        m.submodules.status = status = StatusCounters()
        wiring.connect(m, wiring.flipped(self.rx), link.rx)
        wiring.connect(m, link.tx, wiring.flipped(self.tx))
        wiring.connect(m, link.status, status.port)
        m.d.comb += status.count(link.tally)
        m.submodules.table = table = CalibrationTable()
        serve_registers(m, table, link.registers)
        return m
