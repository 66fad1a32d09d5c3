import os

import pytest

from fliss.sim.cocotb_runner import SIMULATORS, prepare_path, simulator_available


_COCOTB_COUNTS = {}


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
def cocotb_counts():
    """Record cocotb test counts per simulator for the summary at the end of the run."""
    def record(simulator, passed, failed, skipped):
        counts = _COCOTB_COUNTS.setdefault(simulator, [0, 0, 0])
        for index, value in enumerate((passed, failed, skipped)):
            counts[index] += value
    return record


def pytest_terminal_summary(terminalreporter):
    if _COCOTB_COUNTS:
        terminalreporter.section("cocotb tests per simulator")
        for simulator, (passed, failed, skipped) in sorted(_COCOTB_COUNTS.items()):
            terminalreporter.write_line(
                f"{simulator}: {passed} passed, {failed} failed, {skipped} skipped")
