"""``fliss.hdl.lookup``: both forms of a constant table read every entry, and the fill past the
end, at every index."""

import pytest
from amaranth.hdl import Module, Signal
from amaranth.sim import Simulator

from fliss.hdl import lookup


@pytest.mark.parametrize("rom", [False, True])
def test_lookup_reads_every_entry(rom):
    values = [(k * 2654435761) % 1021 for k in range(13)]     # 13 entries of a 4-bit index
    index = Signal(4)
    out = Signal(10)
    m = Module()
    m.d.comb += out.eq(lookup(values, index, 10, fill=777, rom=rom))
    read = []

    async def testbench(ctx):
        for k in range(16):
            ctx.set(index, k)
            read.append(ctx.get(out))

    sim = Simulator(m)
    sim.add_testbench(testbench)
    sim.run()
    assert read == values + [777] * 3
