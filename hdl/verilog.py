"""Verilog from the gateware, for simulators and vendor tools.

``amaranth.back.verilog.convert`` keeps combinational processes as ``always @*`` blocks. A block
that assigns only constants to a slice of a signal has nothing to be sensitive to, and
simulators never run it (Icarus leaves the slice at X, Verilator at 0). Here every process is
lowered to cells first (Yosys ``proc``), so constants become plain ``assign`` statements and the
Verilog means the same in every simulator.
"""

from amaranth._toolchain.yosys import find_yosys
from amaranth.back import rtlil


__all__ = ["convert"]


def convert(component, name, platform=None):
    """Verilog text of ``component`` (a ``wiring.Component``) as module ``name``, elaborated
    for ``platform`` (None: for no FPGA in particular)."""
    rtlil_text = rtlil.convert(component, name=name, platform=platform, emit_src=False)
    yosys = find_yosys(lambda version: version >= (0, 40))
    script = "\n".join([
        f"read_rtlil <<rtlil\n{rtlil_text}\nrtlil",
        "proc",
        "opt_clean",
        "write_verilog -noattr",
    ])
    return yosys.run(["-q", "-"], script, ignore_warnings=True)
