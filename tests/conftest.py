import gc
import os
import warnings

import pytest
from amaranth.hdl import UnusedElaboratable

from fliss.sim.benches.runner import SIMULATORS, prepare_path, simulator_available


_COCOTB_COUNTS = {}

#: Test files whose tests run for minutes; they start first so that parallel workers finish
#: together.
_SLOW_FILES = ("test_cocotb_link.py", "test_cocotb_top.py", "test_cocotb_delay_core.py")


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


def pytest_collection_modifyitems(items):
    items.sort(key=lambda item: item.path.name not in _SLOW_FILES)


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
