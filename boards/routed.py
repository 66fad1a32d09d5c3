"""Routed netlists: a board's design as nextpnr placed and routed it, read back as Verilog and
simulated with Yosys's models of the packed cells.

:func:`place_and_route` runs the nextpnr command of the board's bitstream build (from the build
script that :func:`fliss.boards.netlist.synthesize` writes) on the synthesized JSON, with
``--write`` (the routed design) and ``--sdf`` (its delays) in place of the bitstream, and reads
the routed JSON back into Yosys to write Verilog. :func:`routed_simulation_sources` gives what a
simulator needs around it: the wrapper of :mod:`fliss.boards.netlist` and the patched cell
models, plus models of the packed cells Yosys's models lack.
"""

import json
import shlex
import subprocess

from .build import toolchain_env
from .netlist import (PLL_LOCK, WRAPPER, Netlist, bit_vector, simulation_sources,
                      write_if_changed)


__all__ = ["ROUTED_ICE40_CELLS", "place_and_route", "routed_simulation_sources"]


#: Models of the iCE40 cells that nextpnr's routed design has and Yosys's models lack: its PLL
#: (as the synthesized netlist's, locked by the wrapper) and its SPRAM, the SB_SPRAM256KA with
#: its buses split into bits.
ROUTED_ICE40_CELLS = f"""module ICESTORM_PLL(input BYPASS, input RESETB, output LOCK);
    parameter DELAY_ADJMODE_FB = 0, DELAY_ADJMODE_REL = 0, DIVF = 0, DIVQ = 0, DIVR = 0,
              ENABLE_ICEGATE_PORTA = 0, ENABLE_ICEGATE_PORTB = 0, FDA_FEEDBACK = 0,
              FDA_RELATIVE = 0, FEEDBACK_PATH = 0, FILTER_RANGE = 0, PLLOUT_SELECT_A = 0,
              PLLOUT_SELECT_B = 0, PLLTYPE = 0, SHIFTREG_DIVMODE = 0, TEST_MODE = 0;
    assign LOCK = {PLL_LOCK};
endmodule

module ICESTORM_SPRAM({", ".join(
    [f"ADDRESS_{n}" for n in range(14)] + [f"DATAIN_{n}" for n in range(16)] +
    [f"MASKWREN_{n}" for n in range(4)] + [f"DATAOUT_{n}" for n in range(16)] +
    ["WREN", "CHIPSELECT", "CLOCK", "STANDBY", "SLEEP", "POWEROFF"])});
    input {", ".join([f"ADDRESS_{n}" for n in range(14)] + [f"DATAIN_{n}" for n in range(16)] +
                     [f"MASKWREN_{n}" for n in range(4)])};
    input WREN, CHIPSELECT, CLOCK, STANDBY, SLEEP, POWEROFF;
    output {", ".join(f"DATAOUT_{n}" for n in range(16))};
    SB_SPRAM256KA spram (
        .ADDRESS({bit_vector("ADDRESS_", 14)}), .DATAIN({bit_vector("DATAIN_", 16)}),
        .MASKWREN({bit_vector("MASKWREN_", 4)}), .WREN(WREN), .CHIPSELECT(CHIPSELECT),
        .CLOCK(CLOCK), .STANDBY(STANDBY), .SLEEP(SLEEP), .POWEROFF(POWEROFF),
        .DATAOUT({bit_vector("DATAOUT_", 16)}));
endmodule
"""

# Options of the build's nextpnr command that write the bitstream's input or a log: replaced.
_OUTPUT_OPTIONS = {"--quiet": 0, "--log": 1, "--asc": 1, "--textcfg": 1}


def _nextpnr_command(folder, name, env):
    # The bitstream build's nextpnr command, from its script, without its outputs.
    script = (folder / f"build_{name}.sh").read_text()
    line = next(line for line in script.splitlines() if line.startswith('"$NEXTPNR_'))
    words = shlex.split(line)
    command, skip = [env[words[0].lstrip("$")]], 0
    for word in words[1:]:
        if skip:
            skip -= 1
        elif word in _OUTPUT_OPTIONS:
            skip = _OUTPUT_OPTIONS[word]
        else:
            command.append(word)
    return command


def place_and_route(netlist):
    """Place and route ``netlist`` as its bitstream build does (the build's nextpnr command,
    ``--timing-allow-fail``), and read the routed design back as Verilog; returns a
    :class:`~fliss.boards.netlist.Netlist` of it (top level ``top``).

    On the iCE40, the routed design's PLL has no output and the clock's global buffer no input
    (the dedicated path between them is not in the JSON), so :func:`routed_simulation_sources`
    drives that net from the wrapper's clock; and nextpnr's constant-one net has no driver, so
    it is tied to 1 here."""
    folder = netlist.path.parent
    name = f"fliss_{netlist.board}"
    routed = folder / f"{name}.routed.v"
    env = toolchain_env(netlist.board)
    if not routed.exists() or routed.stat().st_mtime < netlist.path.stat().st_mtime:
        command = _nextpnr_command(folder, name, env)
        process = subprocess.run(
            [*command, "--quiet", "--log", f"{name}.routed.log", "--timing-allow-fail",
             "--write", f"{name}.routed.json", "--sdf", f"{name}.routed.sdf"],
            cwd=folder, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        if process.returncode != 0:
            raise RuntimeError(f"nextpnr failed on the {netlist.board} design (status "
                               f"{process.returncode}); log in {folder / f'{name}.routed.log'}")
        nets = json.loads((folder / f"{name}.routed.json").read_text())["modules"]["top"][
            "netnames"]
        # (nextpnr's constant-one net, where it has no driver in the JSON: the fabric ties it
        # high)
        tie = "connect -set $PACKER_VCC_NET 1'1; " if "$PACKER_VCC_NET" in nets else ""
        subprocess.run([env["YOSYS"], "-q", "-p", f"read_json {name}.routed.json; {tie}"
                        f"write_verilog -noattr {name}.routed.v"],
                       cwd=folder, env=env, check=True, capture_output=True)
    return Netlist(netlist.board, routed, "top", netlist.design, netlist.clock_hz, 0.0)


def routed_simulation_sources(routed):
    """:func:`~fliss.boards.netlist.simulation_sources` of a routed design from
    :func:`place_and_route`: the iCEBreaker's only (the ECP5's raises :exc:`ValueError`)."""
    if routed.board != "icebreaker":
        # (nextpnr's ECP5 design splits LUT RAM into TRELLIS_COMB in DPRAM mode and a
        # TRELLIS_RAMW, and leaves its constant-zero net, the pads' T, without a driver)
        raise ValueError("The ECP5's routed design is not simulated: Yosys's ECP5 models have "
                         "no TRELLIS_RAMW")
    sources, defines = simulation_sources(routed, sim_dir=routed.path.parent / "sim_routed")
    wrapper, extra = sources[0], sources[0].with_name("routed_cells.v")
    text = wrapper.read_text().replace(
        "endmodule", "  // (the routed design's clock net, driven by a path its JSON leaves out)\n"
        "  initial force board.clk = clk;\nendmodule")
    write_if_changed(wrapper.with_name(f"{WRAPPER}_routed.v"), text)
    write_if_changed(extra, ROUTED_ICE40_CELLS)
    return [wrapper.with_name(f"{WRAPPER}_routed.v"), *sources[1:], extra], defines
