"""Single-port RAM: an iCE40 UltraPlus SPRAM block, or a generic memory elsewhere."""

from amaranth.hdl import C, ClockSignal, Instance, MemoryData, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out


__all__ = ["SPRAM_DEVICES", "SPRAM_DEPTH", "SPRAM_WIDTH", "has_spram", "SinglePortRam"]


#: iCE40 devices with ``SB_SPRAM256KA`` blocks (four each).
SPRAM_DEVICES = ("iCE40UP5K", "iCE40UP3K")
#: Words of one ``SB_SPRAM256KA``.
SPRAM_DEPTH = 16384
#: Bits per word of one ``SB_SPRAM256KA``.
SPRAM_WIDTH = 16


def has_spram(platform):
    """Whether ``platform`` is an iCE40 platform whose device has ``SB_SPRAM256KA`` blocks."""
    if platform is None:
        return False
    from amaranth.vendor import SiliconBluePlatform
    return isinstance(platform, SiliconBluePlatform) and \
        getattr(platform, "device", None) in SPRAM_DEVICES


class SinglePortRam(wiring.Component):
    """Single-port synchronous RAM: one address for reads and writes, one access per cycle.

    In each cycle the RAM either writes ``write_data`` to ``addr`` (``write_en`` high) or reads
    ``addr`` (``write_en`` low): ``read_data`` shows the word in the next cycle, like a
    synchronous read port; a read after a write to the same address sees the new word. In a
    write cycle nothing is read: ``read_data`` keeps its value in the next cycle. That is what
    the yosys simulation model of ``SB_SPRAM256KA`` (``techlibs/ice40/cells_sim.v``) does; users
    that want to be safe on silicon should not rely on ``read_data`` after a write cycle (the
    histogram never does).

    On an iCE40 UltraPlus platform (:func:`has_spram`: an amaranth ``SiliconBluePlatform``,
    formerly ``LatticeICE40Platform``, with device ``iCE40UP5K`` or ``iCE40UP3K``) the RAM is
    one ``SB_SPRAM256KA`` block: ``depth`` up to 16384 words of exactly 16 bits, all four bytes
    written at once, always selected, never in standby, sleep or power-off. Its contents are
    undefined at power-up: clear what you use before relying on it. Elsewhere (no platform, as
    in simulation or Verilog generation, or other FPGAs) it is an
    :class:`amaranth.lib.memory.Memory` with one read port and one write port on the same
    address, zero at power-up, with the same timing.

    Parameters
    ----------
    depth : int
        Words of the RAM.
    width : int
        Bits per word.
    domain : str
        Clock domain of the RAM.

    Members
    -------
    addr : In(range(depth))
        Word read or written in this cycle.
    write_en : In(1)
        Write ``write_data`` to ``addr`` in this cycle instead of reading it.
    write_data : In(width)
        Word to write.
    read_data : Out(width)
        The word read in the previous cycle (held after a write cycle).

    Attributes
    ----------
    data : :class:`amaranth.hdl.MemoryData`
        Contents of the generic memory, for testbenches (``ctx.set(ram.data[addr], value)``);
        unused with ``SB_SPRAM256KA``.
    """

    def __init__(self, *, depth, width, domain="sync"):
        if not isinstance(depth, int) or depth < 1:
            raise ValueError(f"Depth must be a positive integer, not {depth!r}")
        if not isinstance(width, int) or width < 1:
            raise ValueError(f"Width must be a positive integer, not {width!r}")
        self.depth = depth
        self.width = width
        self.domain = domain
        self.data = MemoryData(shape=width, depth=depth, init=[])
        super().__init__({
            "addr":       In(range(depth)),
            "write_en":   In(1),
            "write_data": In(width),
            "read_data":  Out(width),
        })

    def elaborate(self, platform):
        if has_spram(platform) and (self.depth > SPRAM_DEPTH or self.width != SPRAM_WIDTH):
            raise ValueError(f"SB_SPRAM256KA on {platform.device} holds up to "
                             f"{SPRAM_DEPTH} words of {SPRAM_WIDTH} bits, not "
                             f"{self.depth} words of {self.width} bits")

        m = Module()

        if has_spram(platform):
            address = Signal(14)                    # the cell's address width
            m.d.comb += address.eq(self.addr)
            m.submodules.spram = Instance(
                "SB_SPRAM256KA",
                i_ADDRESS=address,
                i_DATAIN=self.write_data,
                i_MASKWREN=C(0b1111, 4),
                i_WREN=self.write_en,
                i_CHIPSELECT=C(1, 1),
                i_CLOCK=ClockSignal(self.domain),
                i_STANDBY=C(0, 1),
                i_SLEEP=C(0, 1),
                i_POWEROFF=C(1, 1),                 # active low: powered
                o_DATAOUT=self.read_data,
            )
        else:
            m.submodules.memory = memory = Memory(data=self.data)
            read_port = memory.read_port(domain=self.domain)
            write_port = memory.write_port(domain=self.domain)
            m.d.comb += [
                read_port.addr.eq(self.addr),
                read_port.en.eq(~self.write_en),   # no read in a write cycle: data holds
                write_port.addr.eq(self.addr),
                write_port.en.eq(self.write_en),
                write_port.data.eq(self.write_data),
                self.read_data.eq(read_port.data),
            ]

        return m
