"""Pairs for the equivalence proofs beyond the pairing by name: the live bits of wires with dead
bits, and the registers that synthesis stored inverted.

A netlist leaves the bits that synthesis found dead undriven (``1'hx``, :func:`dead_bits`, read
bit by bit), and ``equiv_make -blacklist`` can only leave out a whole wire: its other bits are
paired one by one (:func:`alive_pairs`; the delay core's m-sequence register is named in its
iCE40 netlist only as bits of the delay payload, whose unread bits are dead).

The iCE40's flip-flops power up at 0, so ``synth_ice40`` stores a register bit whose init value
is 1 inverted (a flip-flop of the inverse, the inversion absorbed into the LUTs around it), and
leaves the RTL's name of that bit undriven. :func:`inverted_pairs` finds, for each dead bit, the
netlist flip-flop that holds its inverse: both designs are simulated side by side (Icarus, the
family's cell models) on random inputs, and a bit is paired with the one flip-flop whose output
is its inverse in every cycle after the reset (the bit having taken both values).
The proof then pairs the RTL bit with the netlist's (a new wire on each side,
:func:`gold_script` and :func:`gate_text`), as ``equiv_make`` pairs the others by name; a
wrong pairing makes the proof fail, never pass.
"""

import re
import shutil
import subprocess
from pathlib import Path


__all__ = ["widths", "dead_bits", "alive_pairs", "inverted_pairs", "gold_script", "gate_text"]


#: Cycles simulated, and the reset's length at their start.
CYCLES, RESET_CYCLES = 600, 2

_PORT = re.compile(r"^\s*(input|output)\s+(?:\[(\d+):0\]\s+)?(\S+);", re.M)
_FF = re.compile(r"\b(SB_DFF\w*|TRELLIS_FF)\s+\S+\s*\((.*?)\);", re.S)


_DECL = re.compile(r"^\s*(?:wire|reg|input|output)\s+(?:\[(\d+):(\d+)\]\s+)?\\?(\S+)\s*(?:;|=)",
                   re.M)
_CONST = re.compile(r"(\d+)'([hbd])([0-9a-fA-FxXzZ]+)$")
_SIGNAL = re.compile(r"\\?([^\s\[\]{},:]+)\s*(?:\[(\d+)(?::(\d+))?\])?$")


def widths(text):
    """The width of each wire, register and port that the Verilog ``text`` declares (None for
    a one-bit one declared without a range): name -> width."""
    found = {}
    for high, low, name in _DECL.findall(text):
        found.setdefault(name, int(high) - int(low) + 1 if high else None)
    return found


def _term_bits(term, declared):
    # A concatenation's term, its bits from the most significant: "x" for an `x` constant bit,
    # "c" for another constant bit, (name, bit) for a wire's bit
    constant = _CONST.match(term)
    if constant:
        size, base, digits = int(constant.group(1)), constant.group(2), constant.group(3).lower()
        if base == "d":
            return ["c"] * size
        per = 4 if base == "h" else 1
        bits = ["x" if digit == "x" else "c" for digit in digits for _ in range(per)]
        return (["c"] * size + bits)[-size:]
    signal = _SIGNAL.match(term)
    if signal is None:
        raise ValueError(f"not a wire or a constant: {term!r}")
    name, high, low = signal.groups()
    if high is not None:
        return [(name, bit) for bit in range(int(high), int(low or high) - 1, -1)]
    width = declared.get(name)
    return [(name, None)] if width is None else [(name, bit) for bit in range(width - 1, -1, -1)]


def _side_bits(side, declared):
    side = side.strip()
    terms = side[1:-1].split(",") if side.startswith("{") else [side]
    return [bit for term in terms for bit in _term_bits(term.strip(), declared)]


def dead_bits(gate):
    """The wire bits that the netlist ``gate`` (text) assigns an ``x`` to, alone or in a
    concatenation: ``(name, bit)`` (``bit`` None for a one-bit wire), in the order assigned."""
    declared = widths(gate)
    found = []
    for target, value in re.findall(r"^\s*assign (.+?) = (.+);$", gate, re.M):
        if not re.search(r"\d+'[hb][0-9a-f]*x", value):
            continue
        targets, values = _side_bits(target, declared), _side_bits(value, declared)
        # (aligned from the least significant bit)
        for key, bit in zip(reversed(targets), reversed(values)):
            if bit == "x" and key not in found:
                found.append(key)
    return found


def alive_pairs(gate, dead):
    """The other bits of each wire with ``dead`` bits (those that the pairing by name leaves
    out with the whole name), paired as they are: ``(name, bit) -> (gate signal, False)``."""
    declared = widths(gate)
    pairs = {}
    for name in dict.fromkeys(name for name, _ in dead):
        width = declared.get(name)
        for bit in range(width or 0):
            if (name, bit) not in dead:
                pairs[name, bit] = (f"\\{name} [{bit}] ", False)
    return pairs


def _ref(instance, name, bit):
    return f"{instance}.\\{name} " + ("" if bit is None else f"[{bit}]")


def inverted_pairs(folder, models, bits, *, seed=1):
    """For each of ``bits`` (``(name, bit)`` of the RTL ``gold.il`` in ``folder``, dead in its
    netlist ``gate.v``) that the RTL's Verilog (``pairs_gold.v``) holds, the one netlist
    flip-flop output that is its inverse: a dict ``(name, bit) -> (gate signal (Verilog),
    True)``. ``models``: the cell models' Verilog file. Empty without Icarus (``iverilog``)."""
    folder = Path(folder)
    if not bits or shutil.which("iverilog") is None:
        return {}
    gate = (folder / "gate.v").read_text()
    gold_widths = widths((folder / "pairs_gold.v").read_text())
    bits = [(name, bit) for name, bit in bits
            if name in gold_widths and (bit is None) == (gold_widths[name] is None)]
    if not bits:
        return {}
    header = gate[gate.index("module top("):]
    header = header[:header.index("endmodule")]
    ports = [(kind, int(high) + 1 if high else 1, name.lstrip("\\"))
             for kind, high, name in _PORT.findall(header)]
    # (an escaped name ends at a space)
    outputs = [q.strip() + " " for _, body in _FF.findall(header)
               for q in re.findall(r"\.Q\(([^)]*)\)", body)]
    _simulate(folder, models, ports, [_ref("g", name, bit) for name, bit in bits]
              + [f"n.{q}" for q in outputs], seed)
    run = subprocess.run(["vvp", "-n", "pairs.vvp"], cwd=folder, capture_output=True, text=True)
    rows = [line.strip() for line in run.stdout.splitlines()
            if re.fullmatch(r"[01xz]+", line.strip())][RESET_CYCLES + 1:]
    if not rows:
        return {}
    # the concatenation's bits, first shown first
    columns = list(zip(*rows))
    gate_columns = columns[len(bits):]
    pairs = {}
    for key, column in zip(bits, columns):
        if set(column) != {"0", "1"}:
            continue
        inverse = tuple("1" if v == "0" else "0" for v in column)
        matches = [q for q, other in zip(outputs, gate_columns) if other == inverse]
        if len(matches) == 1:
            pairs[key] = (matches[0], True)
    return pairs


def _simulate(folder, models, ports, shown, seed):
    # The test bench of the RTL (`gold`) and the netlist (`gate`) side by side, compiled
    inputs = [(width, name) for kind, width, name in ports if kind == "input" and name != "clk"]
    lines = ["`timescale 1ns/1ps", "module fliss_pairs;", "  reg clk = 0;", "  integer i;",
             f"  integer seed = {seed};"]
    lines += [f"  reg [{width - 1}:0] {name} = 0;" for width, name in inputs]
    connections = ", ".join(f".{name}({name if kind == 'input' else ''})"
                            for kind, _, name in ports)
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
    (folder / "pairs_tb.v").write_text("\n".join(lines))
    gate = (folder / "gate.v").read_text()
    (folder / "pairs_gate.v").write_text(gate.replace("module top(", "module gate(", 1))
    subprocess.run(
        ["iverilog", "-g2012", "-DNO_ICE40_DEFAULT_ASSIGNMENTS", "-DICE40_U", "-o", "pairs.vvp",
         "pairs_tb.v", "pairs_gold.v", "pairs_gate.v", str(models)],
        cwd=folder, capture_output=True, text=True)


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
