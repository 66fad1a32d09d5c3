"""The calibration table: raw code -> fine time, in block RAM, written and read by the host."""

from amaranth.hdl import Module, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from . import CODE_BITS, TABLE_BITS, TAP_S, UNIT_S


__all__ = ["nominal_table", "CalibrationTable", "serve_registers"]


def nominal_table(depth=1 << CODE_BITS):
    """The table at reset: every tap as wide as the timing model says (:data:`TAP_S`), code ``c``
    at ``(c - 1/2)`` taps before the sampling edge, in table units (at least 0)."""
    return [max(0, round((code - 0.5) * TAP_S / UNIT_S)) for code in range(depth)]


class CalibrationTable(wiring.Component):
    """Calibration table in block RAM: ``2**CODE_BITS`` entries of ``TABLE_BITS`` bits, the fine
    time of each raw code before the sampling edge, in units of
    :data:`~fliss.hdl.finetdc.UNIT_S` (computed on the host by
    :func:`fliss.analysis.calibration.table`). Reset to :func:`nominal_table`.

    The host reaches it through a pointer: ``seek`` sets the pointer to ``seek_address``;
    ``write`` writes ``write_data`` at the pointer (the one just set, if both come in one
    cycle) and moves the pointer on by one. ``read_data`` is a register loaded from the block
    RAM at every clock edge: from the third cycle after a ``seek`` or a ``write`` (the strobe's
    cycle counted as 0) it holds the entry at the new pointer. (A register, so that the block
    RAM's output, slow on the ECP5, does not go straight into the register file's read
    multiplexer.)

    Members
    -------
    code : In(CODE_BITS)
        Raw code to look up.
    fine : Out(TABLE_BITS)
        Its entry, two cycles later: the block RAM's read, then a register (the ECP5's block
        RAM output is slow, 5.8 ns from the clock in nextpnr's timing model: it goes to a
        flip-flop, not into the subtraction after it).
    seek : In(1)
    seek_address : In(CODE_BITS)
    write : In(1)
    write_data : In(TABLE_BITS)
    read_data : Out(TABLE_BITS)
        The host's side, as above.
    """

    code:         In(CODE_BITS)
    fine:         Out(TABLE_BITS)
    seek:         In(1)
    seek_address: In(CODE_BITS)
    write:        In(1)
    write_data:   In(TABLE_BITS)
    read_data:    Out(TABLE_BITS)

    def elaborate(self, platform):
        m = Module()

        m.submodules.memory = memory = Memory(shape=TABLE_BITS, depth=1 << CODE_BITS,
                                              init=nominal_table())

        # Lookup
        lookup = memory.read_port()
        m.d.comb += lookup.addr.eq(self.code)
        m.d.sync += self.fine.eq(lookup.data)

        # The host's pointer, write and read back
        pointer = Signal(CODE_BITS)
        address = Signal(CODE_BITS)
        m.d.comb += address.eq(pointer)
        with m.If(self.seek):
            m.d.comb += address.eq(self.seek_address)
        write = memory.write_port()
        back = memory.read_port(transparent_for=[write])
        m.d.comb += [
            write.addr.eq(address), write.data.eq(self.write_data), write.en.eq(self.write),
            back.addr.eq(address),
        ]
        m.d.sync += self.read_data.eq(back.data)
        with m.If(self.seek | self.write):
            m.d.sync += pointer.eq(address + self.write)

        return m


def serve_registers(m, table, registers):
    """Connect ``table``'s host side to a :class:`~fliss.hdl.regfile.RegisterFile`'s
    ``table_*`` strobes and ``fine_tdc`` settings, and give the register file its read back
    (as a build with the fine TDC does; for benches of the link without the TDC)."""
    m.d.comb += [
        table.seek.eq(registers.table_seek),
        table.seek_address.eq(registers.fine_tdc.table_address),
        table.write.eq(registers.table_write),
        table.write_data.eq(registers.fine_tdc.table_data),
        registers.table_read.eq(table.read_data),
    ]
