"""Registers that synthesis stored inverted, paired with the RTL's for the equivalence proofs.

The iCE40's flip-flops power up at 0, so ``synth_ice40`` stores a register bit whose init value
is 1 inverted (a flip-flop of the inverse, the inversion absorbed into the LUTs around it), and
leaves the RTL's name of that bit undriven (``1'hx``). :func:`inverted_pairs` finds, for each
such bit, the netlist flip-flop that holds its inverse: both designs are simulated side by side
(Icarus, the family's cell models) on random inputs, and a bit is paired with the one flip-flop
whose output is its inverse in every cycle after the reset (the bit having taken both values).
The proof then pairs the RTL bit with the inverse of that flip-flop's output (a new wire on each
side, :func:`gold_script` and :func:`gate_text`), as ``equiv_make`` pairs the others by name; a
wrong pairing makes the proof fail, never pass.
"""

import re
import shutil
import subprocess
from pathlib import Path


__all__ = ["dead_bits", "inverted_pairs", "gold_script", "gate_text"]


#: Cycles simulated, and the reset's length at their start.
CYCLES, RESET_CYCLES = 600, 2

_PORT = re.compile(r"^\s*(input|output)\s+(?:\[(\d+):0\]\s+)?(\S+);", re.M)
_FF = re.compile(r"\b(SB_DFF\w*|TRELLIS_FF)\s+\S+\s*\((.*?)\);", re.S)


def _bits(target):
    # `\name [3]`, `\name [7:4]`, `name` (width unknown: bit 0) -> (name, bit) ...
    for name, high, low in re.findall(r"\\?([^\s\[\]{},:]+)(?:\s*\[(\d+)(?::(\d+))?\])?",
                                      target):
        if high == "":
            yield name, None
        else:
            for bit in range(int(low or high), int(high) + 1):
                yield name, bit


def dead_bits(gate):
    """The bits of every wire the netlist ``gate`` (text) assigns an ``x`` to, in part or in
    all: ``(name, bit)`` (``bit`` None for a one-bit wire)."""
    found = []
    for target, value in re.findall(r"^\s*assign (.+?) = (.+);$", gate, re.M):
        if re.search(r"\d+'h[0-9a-f]*x", value):
            found += [key for key in _bits(target.strip().strip("{}")) if key not in found]
    return found


def _ref(instance, name, bit):
    return f"{instance}.\\{name} " + ("" if bit is None else f"[{bit}]")


def inverted_pairs(folder, models, bits, *, seed=1):
    """For each of ``bits`` (``(name, bit)`` of the RTL ``gold.il`` in ``folder``, dead in its
    netlist ``gate.v``) that is a register bit of the RTL (its Verilog ``pairs_gold.v``), the
    netlist flip-flop output that is its inverse, and for the other bits of those registers,
    their own netlist bit: a dict ``(name, bit) -> (gate signal (Verilog), inverted)``.
    ``models``: the cell models' Verilog file. Empty without Icarus (``iverilog``)."""
    folder = Path(folder)
    if not bits or shutil.which("iverilog") is None:
        return {}
    gate = (folder / "gate.v").read_text()
    # (only the RTL's registers: `reg` in its Verilog; their width)
    registers = {name: int(high) + 1 if high else None for high, name in re.findall(
        r"^\s*reg (?:\[(\d+):0\] )?\\?(\S+)\s*(?:=|;)", (folder / "pairs_gold.v").read_text(),
        re.M)}
    bits = [(name, bit) for name, bit in bits if name in registers]
    every = [(name, bit) for name, width in registers.items()
             for bit in (range(width) if width else [None])]
    header = gate[gate.index("module top("):]
    header = header[:header.index("endmodule")]
    ports = [(kind, int(high) + 1 if high else 1, name.lstrip("\\"))
             for kind, high, name in _PORT.findall(header)]
    # (an escaped name ends at a space)
    outputs = [q.strip() + " " for _, body in _FF.findall(header)
               for q in re.findall(r"\.Q\(([^)]*)\)", body)]
    inputs = [(width, name) for kind, width, name in ports if kind == "input" and name != "clk"]
    lines = ["`timescale 1ns/1ps", "module fliss_pairs;", "  reg clk = 0;", "  integer i;"]
    lines += [f"  reg [{width - 1}:0] {name} = 0;" for width, name in inputs]
    connections = ", ".join(f".{name}({name if kind == 'input' else ''})"
                            for kind, _, name in ports)
    shown = [_ref("g", name, bit) for name, bit in every] + [f"n.{q}" for q in outputs]
    lines += [f"  gold g({connections});", f"  gate n({connections});", "  initial begin",
              f"    for (i = 0; i < {CYCLES}; i = i + 1) begin"]
    for width, name in inputs:
        if name == "rst":
            lines.append(f"      rst = i < {RESET_CYCLES};")
        else:
            words = ", ".join(["$random(seed)"] * ((width + 31) // 32))
            lines.append(f"      {name} = {{{words}}};")
    lines += ["      #5 clk = 1; #5 clk = 0;",
              f"      $display(\"%b\", {{{', '.join(shown)}}});",
              "    end", "    $finish;", "  end", "endmodule", ""]
    lines.insert(4, f"  integer seed = {seed};")
    (folder / "pairs_tb.v").write_text("\n".join(lines))
    (folder / "pairs_gate.v").write_text(gate.replace("module top(", "module gate(", 1))
    process = subprocess.run(
        ["iverilog", "-g2012", "-DNO_ICE40_DEFAULT_ASSIGNMENTS", "-DICE40_U", "-o", "pairs.vvp",
         "pairs_tb.v", "pairs_gold.v", "pairs_gate.v", str(models)],
        cwd=folder, capture_output=True, text=True)
    if process.returncode != 0:
        return {}
    run = subprocess.run(["vvp", "-n", "pairs.vvp"], cwd=folder, capture_output=True, text=True)
    rows = [line.strip() for line in run.stdout.splitlines() if re.fullmatch(r"[01xz]+", line.strip())]
    rows = rows[RESET_CYCLES + 1:]
    # the concatenation's bits, first shown first
    columns = list(zip(*rows))
    gold = dict(zip(every, columns[:len(every)]))
    gate_columns = columns[len(every):]
    pairs = {}
    for key in bits:
        column = gold[key]
        if set(column) != {"0", "1"}:
            continue
        inverse = tuple("1" if v == "0" else "0" for v in column)
        matches = [q for q, other in zip(outputs, gate_columns) if other == inverse]
        if len(matches) == 1:
            pairs[key] = (matches[0], True)
    # netlist flip-flops named by synthesis (`..._SB_...`: of no RTL name), paired with an
    # RTL register bit that they equal or invert (the first of those not paired yet)
    by_value = {}
    for key, column in gold.items():
        if set(column) == {"0", "1"}:
            by_value.setdefault(column, []).append(key)
    used = set(pairs.values())
    for q, column in zip(outputs, gate_columns):
        if "_SB_" not in q or (q, True) in used:
            continue
        inverse = tuple("1" if v == "0" else "0" for v in column)
        for inverted, value in ((False, column), (True, inverse)):
            free = [key for key in by_value.get(value, []) if key not in pairs]
            if free:
                pairs[free[0]] = (q, inverted)
                break
    # the name is left out of the pairing by name: pair its other bits as they are
    for name in {name for name, _ in pairs}:
        for bit in range(registers[name] or 0):
            if (name, bit) not in pairs and (name, bit) not in bits:
                pairs[name, bit] = (f"\\{name} [{bit}] ", False)
    return pairs


def gold_script(pairs):
    """Yosys commands that add the RTL side of each pair (``fliss_pair_<k>``)."""
    lines = []
    for k, (name, bit) in enumerate(pairs):
        lines += [f"add -wire fliss_pair_{k} 1",
                  f"connect -set fliss_pair_{k} {name}" + ("" if bit is None else f"[{bit}]")]
    return lines


def gate_text(gate, pairs):
    """The netlist with the netlist side of each pair: ``fliss_pair_<k>``, the inverse of its
    flip-flop's output (or the output as it is, for the other bits of a register with bits
    stored inverted, which the pairing by name leaves out with them)."""
    wires = "".join(f"  (* keep *) wire fliss_pair_{k};\n  assign fliss_pair_{k} = "
                    f"{'~' if inverted else ''}({q});\n"
                    for k, (q, inverted) in enumerate(pairs.values()))
    end = gate.rindex("endmodule")
    return gate[:end] + wires + gate[end:]
