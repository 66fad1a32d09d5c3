"""Size of the FLISS top level on the iCEBreaker's iCE40UP5K: logic cells after
packing, against the 5 280 of the chip.

Synthesises each design with the YoWASP tools (``pip install -e '.[boards]'``) and runs nextpnr
up to packing only (``--pack-only``): a design that does not fit is measured too, quickly. The
baseline, in the same run, is the delay core alone (``core_probe.DelayCoreProbe``, its settings
shifted in from a pin).

Goal: ``FlissTop`` within the chip, with room for placement (nextpnr places 89 % in about a
minute, and failed on 4 958 cells, 94 %). The iCEBreaker carries ``fliss_top_up5k`` (the
options of ``fliss.hdl.top.SMALL``); ``fliss_top_spram`` is every feature, for comparison.

Usage: python benchmarks/up5k_fit.py
"""

import argparse
import re
import subprocess
import tempfile
import time
from pathlib import Path

from fliss.boards import BoardTop, platform_class
from fliss.boards.build import BOARD_CLOCK_HZ, load_design, toolchain_env

from core_probe import DelayCoreProbe


DESIGNS = [
    (DelayCoreProbe,                 "baseline: the delay core alone"),
    ("fliss.boards:fliss_top_spram", "FlissTop, histogram in SPRAM"),
    ("fliss.boards:fliss_top_up5k",  "FlissTop, the iCEBreaker build (SMALL)"),
    ("fliss.boards:fliss_top_up5k_keyed", "SMALL with the keyed delay source"),
]


def packed_cells(design, build_dir):
    """Logic cells, block RAMs and SPRAMs of ``design`` on the UP5K after packing."""
    platform = platform_class("icebreaker")(clock_hz=BOARD_CLOCK_HZ["icebreaker"])
    factory = design if callable(design) else load_design(design)
    plan = platform.prepare(BoardTop(factory), name="fliss_icebreaker",
                            nextpnr_opts=["--pack-only"])
    plan.extract(str(build_dir))
    # (nextpnr ends with an error after packing, with no placement to write: its log holds
    # the counts all the same)
    subprocess.run(["sh", f"{plan.script}.sh"], cwd=build_dir,
                   env=toolchain_env("icebreaker", "yowasp"),
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    log_file = Path(build_dir, "fliss_icebreaker.tim")
    log = log_file.read_text(errors="replace") if log_file.exists() else ""
    found = {}
    for cell in ("ICESTORM_LC", "ICESTORM_RAM", "ICESTORM_SPRAM"):
        match = re.search(rf"{cell}:\s+(\d+)/\s*(\d+)", log)
        if match is None:
            raise RuntimeError(f"no {cell} count in the log of {design}; logs in {build_dir}")
        found[cell] = (int(match[1]), int(match[2]))
    return found


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="fliss-up5k-") as root:
        for number, (design, label) in enumerate(DESIGNS):
            start = time.monotonic()
            cells = packed_cells(design, Path(root, str(number)))
            used, available = cells["ICESTORM_LC"]
            share = 100 * used / available
            print(f"  {label:50} logic cells {used:5} / {available} ({share:3.0f} %)"
                  f"  BRAM {cells['ICESTORM_RAM'][0]:2}  SPRAM {cells['ICESTORM_SPRAM'][0]}"
                  f"  {time.monotonic() - start:3.0f} s  ({getattr(design, '__name__', design)})",
                  flush=True)


if __name__ == "__main__":
    main()
