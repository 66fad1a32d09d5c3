"""Block RAM with a registered read: an ECP5 ``DP16KD`` with its output register, or a generic
memory elsewhere."""

from types import SimpleNamespace

from amaranth.hdl import C, ClockSignal, Instance, MemoryData, Module, Signal
from amaranth.lib import wiring
from amaranth.utils import ceil_log2
from amaranth.lib.memory import Memory, ReadPort, WritePort
from amaranth.lib.wiring import In, Out


__all__ = ["DP16KD_DEPTH", "DP16KD_WIDTH", "has_dp16kd", "check_registered_read",
           "reads_registered", "byte_ram", "RegisteredRam"]


#: Words of one ``DP16KD`` as the histogram uses it (1024 words of 18 bits).
DP16KD_DEPTH = 1024
#: Bits of a word of one ``DP16KD`` of :data:`DP16KD_DEPTH` words (wider words take more).
DP16KD_WIDTH = 18


def has_dp16kd(platform):
    """Whether ``platform`` is an ECP5 platform (``DP16KD`` block RAM)."""
    if platform is None:
        return False
    from amaranth.vendor import LatticePlatform
    return isinstance(platform, LatticePlatform) and getattr(platform, "family", None) == "ecp5"


def check_registered_read(choice):
    """Refuse a ``registered_read`` parameter (of a block that reads a buffer either through a
    :class:`RegisteredRam` or a plain memory) that is not ``None``, ``False`` or ``True``."""
    if choice not in (None, False, True):
        raise TypeError(f"registered_read must be None, False or True, not {choice!r}")


def reads_registered(choice, platform):
    """Whether a block with ``registered_read=choice`` reads through a :class:`RegisteredRam`
    on ``platform``: ``None`` chooses it on an ECP5 (:func:`has_dp16kd`)."""
    return has_dp16kd(platform) if choice is None else choice


def byte_ram(m, name, depth, registered, *, output_enable=False):
    """Add a buffer of ``depth`` bytes to ``m`` as the submodule ``name``, for a block that
    reads it either way (:func:`reads_registered`): a :class:`RegisteredRam` if ``registered``,
    otherwise an :class:`amaranth.lib.memory.Memory` with a plain read port, not transparent.
    Returns its write port and its read port, both under the names of a memory port's members
    (``addr``, ``data``, ``en``; and ``output_en``, of a :class:`RegisteredRam` with
    ``output_enable``), so that one description drives either."""
    if not registered:
        m.submodules[name] = memory = Memory(shape=8, depth=depth, init=[])
        addr_width = ceil_log2(depth)
        write = WritePort(WritePort.Signature(shape=8, addr_width=addr_width), memory=memory,
                          domain="sync", path=(f"{name}_wr",))
        read = ReadPort(ReadPort.Signature(shape=8, addr_width=addr_width), memory=memory,
                        domain="sync", path=(f"{name}_rd",))
        return write, read
    m.submodules[name] = ram = RegisteredRam(depth=depth, width=8, output_enable=output_enable)
    write = SimpleNamespace(addr=ram.write_addr, data=ram.write_data, en=ram.write_en)
    read = SimpleNamespace(addr=ram.read_addr, data=ram.read_data, en=ram.read_en,
                           **({"output_en": ram.output_en} if output_enable else {}))
    return write, read


class RegisteredRam(wiring.Component):
    """Simple dual-port RAM whose read data is registered twice: a write port and a read port,
    both on the ``domain`` clock.

    A read with ``read_en`` high samples ``read_addr`` at a clock edge; ``read_data`` shows the
    word after the edge that follows (two cycles after the address was set up), and holds while
    no read is made. With ``output_enable``, the second register (``read_data``) moves only in
    cycles with ``output_en`` high: each of the two stalls on its own enable (with ``output_en``
    the same as ``read_en``, a two-stage pipeline: ``read_data`` is the word of the last read but
    one). A write with ``write_en`` high writes ``write_data`` to ``write_addr`` at the edge. A
    read and a write of the same word at the same edge give an undefined word (no user makes
    one). The contents are zero after configuration.

    On an ECP5 platform (:func:`has_dp16kd`) the RAM is ``DP16KD`` blocks in 1024 × 18 mode (one
    for every 18 bits of the word), port A writing, port B reading, with
    ``REGMODE_B = "OUTREG"``: the second register is the block's own output register, so a word
    leaves the block from a register and not from the slow path out of the array (5.8 ns on the
    ULX3S's speed grade, before any routing). Elsewhere (no platform, as in simulation or Verilog
    generation, or other FPGAs) it is an :class:`amaranth.lib.memory.Memory` read port followed
    by a register, with the same timing.
    Yosys ships ``DP16KD`` as a black box, so the instance itself is checked only by the board
    build (placement, routing and timing), not simulated.

    Parameters
    ----------
    depth : int
        Words, at most :data:`DP16KD_DEPTH`.
    width : int
        Bits per word.
    domain : str
        Clock domain of the RAM.
    output_enable : bool
        Whether the second register has an enable, ``output_en`` (see above).

    Members
    -------
    write_addr : In(range(depth))
    write_en : In(1)
    write_data : In(width)
    read_addr : In(range(depth))
    read_en : In(1)
    output_en : In(1)
        Only with ``output_enable``.
    read_data : Out(width)

    Attributes
    ----------
    data : :class:`amaranth.hdl.MemoryData`
        Contents of the generic memory, for testbenches; unused with ``DP16KD``.
    site : str or None
        Where nextpnr places the ``DP16KD`` (its BEL name, as ``"X58/Y46/EBR0"``), for a RAM
        of one block; ``None`` (the default) leaves it to the placer. Set before elaboration.
    """

    def __init__(self, *, depth, width, domain="sync", output_enable=False):
        if not isinstance(depth, int) or not 1 <= depth <= DP16KD_DEPTH:
            raise ValueError(f"Depth must be an integer from 1 to {DP16KD_DEPTH}, not {depth!r}")
        if not isinstance(width, int) or width < 1:
            raise ValueError(f"Width must be a positive integer, not {width!r}")
        self.depth = depth
        self.width = width
        self.domain = domain
        self.output_enable = bool(output_enable)
        self.data = MemoryData(shape=width, depth=depth, init=[])
        self.site = None
        super().__init__({
            "write_addr": In(range(depth)),
            "write_en":   In(1),
            "write_data": In(width),
            "read_addr":  In(range(depth)),
            "read_en":    In(1),
            **({"output_en": In(1)} if self.output_enable else {}),
            "read_data":  Out(width),
        })

    def elaborate(self, platform):
        if self.site is not None and self.width > DP16KD_WIDTH:
            raise ValueError(f"A site places a RAM of one block ({DP16KD_WIDTH} bits), not of "
                             f"{self.width} bits")
        m = Module()

        if has_dp16kd(platform):
            # 1024 x 18: the word address on AD[13:4]; on port A, AD[1:0] are the byte write
            # enables (both set), AD[3:2] unused.
            def address(prefix, value, byte_enables):
                bits = {f"i_{prefix}{n}": C(byte_enables if n < 2 else 0, 1) for n in range(4)}
                for n in range(10):
                    bits[f"i_{prefix}{n + 4}"] = value[n] if n < len(value) else C(0, 1)
                return bits

            def word(prefix, value, direction):
                return {f"{direction}_{prefix}{n}": value[n] if n < len(value) else
                        (C(0, 1) if direction == "i" else Signal(name=f"{prefix}{n}_unused"))
                        for n in range(DP16KD_WIDTH)}

            placed = {} if self.site is None else {"a_BEL": self.site}
            clock = ClockSignal(self.domain)
            zero, one = C(0, 1), C(1, 1)
            for k, low in enumerate(range(0, self.width, DP16KD_WIDTH)):
                high = min(low + DP16KD_WIDTH, self.width)
                m.submodules[f"dp16kd{k}"] = Instance(
                    "DP16KD",
                    p_DATA_WIDTH_A=DP16KD_WIDTH, p_DATA_WIDTH_B=DP16KD_WIDTH,
                    p_REGMODE_A="NOREG", p_REGMODE_B="OUTREG",
                    p_RESETMODE="SYNC", p_ASYNC_RESET_RELEASE="SYNC",
                    p_CSDECODE_A="0b000", p_CSDECODE_B="0b000",
                    p_WRITEMODE_A="NORMAL", p_WRITEMODE_B="NORMAL", p_GSR="AUTO",
                    i_CLKA=clock, i_CEA=one, i_OCEA=one, i_WEA=self.write_en, i_RSTA=zero,
                    i_CSA0=zero, i_CSA1=zero, i_CSA2=zero,
                    i_CLKB=clock, i_CEB=self.read_en,
                    i_OCEB=self.output_en if self.output_enable else one, i_WEB=zero, i_RSTB=zero,
                    i_CSB0=zero, i_CSB1=zero, i_CSB2=zero,
                    **address("ADA", self.write_addr, 1),
                    **word("DIA", self.write_data[low:high], "i"),
                    **address("ADB", self.read_addr, 0),
                    **word("DIB", C(0, DP16KD_WIDTH), "i"),
                    **word("DOB", self.read_data[low:high], "o"),
                    **word("DOA", C(0, 0), "o"),
                    **placed,
                )
        else:
            m.submodules.memory = memory = Memory(data=self.data)
            read_port = memory.read_port(domain=self.domain)
            write_port = memory.write_port(domain=self.domain)
            m.d.comb += [
                read_port.addr.eq(self.read_addr),
                read_port.en.eq(self.read_en),
                write_port.addr.eq(self.write_addr),
                write_port.en.eq(self.write_en),
                write_port.data.eq(self.write_data),
            ]
            if self.output_enable:
                with m.If(self.output_en):
                    m.d[self.domain] += self.read_data.eq(read_port.data)
            else:
                m.d[self.domain] += self.read_data.eq(read_port.data)

        return m
