"""The link of :class:`fliss.hdl.top.FlissTop` without the UART, for fuzzing at one byte per
cycle: :class:`fliss.hdl.link.link.Link` with byte streams for its serial lines and no data
packets, the STATUS counters of its strobes, and the fine TDC's calibration table (the register
file reads ``table_data`` from it, as in a build with the fine TDC). A
:class:`~fliss.sim.benches.wire.WireBench` plays the bench's frames into it and records its
replies."""

from amaranth.hdl import Module
from amaranth.lib import wiring

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.finetdc.table import CalibrationTable, serve_registers
from ...hdl.link.link import Link
from ...hdl.protocol import DEFAULT_BAUD
from ...hdl.protocol import MAX_ENCODED
from ...hdl.status import StatusCounters
from .wire import WireBench


__all__ = ["PLAY_BYTES", "RECORD_BYTES", "LinkTop"]


#: The longest frame the bench sends: an oversize frame, up to ten bytes over the longest a
#: packet encodes to, and its delimiter.
PLAY_BYTES = MAX_ENCODED + 11
#: The bytes of the link's output the bench can read at once.
RECORD_BYTES = 512


class LinkTop(wiring.Component):
    """Frames in, their replies out: the link of the top level, behind a
    :class:`~fliss.sim.benches.wire.WireBench` (its members are the bench's: ``frame``,
    ``length`` and ``go`` in; ``record``, ``received`` and ``answered`` out)."""

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, baud=DEFAULT_BAUD):
        self.clock_hz, self.baud = clock_hz, baud
        self._wire = WireBench(play_bytes=PLAY_BYTES, record_bytes=RECORD_BYTES)
        members = {name: member for name, member in self._wire.signature.members.items()
                   if member.is_port}
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        m.submodules.link = link = Link(clock_hz=self.clock_hz, baud=self.baud, uart=False)
        m.submodules.status = status = StatusCounters()
        m.submodules.wire = wire = self._wire
        wiring.connect(m, wire.o, link.rx)
        wiring.connect(m, link.tx, wire.i)
        for name in ("frame", "length", "go"):
            m.d.comb += getattr(wire, name).eq(getattr(self, name))
        for name in ("record", "received", "answered"):
            m.d.comb += getattr(self, name).eq(getattr(wire, name))
        wiring.connect(m, link.status, status.port)
        m.d.comb += status.count(link.tally)
        m.submodules.table = table = CalibrationTable()
        serve_registers(m, table, link.registers)
        return m
