"""The figures of speed and size live on one page, docs/measurements.md, written by
benchmarks/measurements.py from the benchmarks' output; the reference pages say what the design
is and does, and carry no measurement history."""

import importlib.util
import re
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[2]
PAGE = ROOT / "docs" / "measurements.md"


def _script():
    spec = importlib.util.spec_from_file_location("measurements",
                                                  ROOT / "benchmarks" / "measurements.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_benchmark_script_has_a_section():
    # Each script of benchmarks/ that prints figures is run by the page's script (core_probe.py
    # is the baseline design others build; finetdc_chain.py reads a build folder, named by hand).
    measurements = _script()
    run = {b.script for b in measurements.BENCHMARKS}
    scripts = {path.name for path in (ROOT / "benchmarks").glob("*.py")}
    assert scripts - run == {"measurements.py", "core_probe.py", "finetdc_chain.py"}
    assert all((ROOT / "benchmarks" / script).exists() for script in run
               if not script.startswith("-m "))


def test_the_page_is_the_scripts_output():
    # The page's sections are the script's, in its order, each measured (the command's output
    # in a code block, with the run's date, commit and load) or saying it was not.
    measurements = _script()
    text = PAGE.read_text()
    assert text.startswith("# Measurements\n")
    assert "written by `benchmarks/measurements.py`" in text.split("\n## ", 1)[0]
    sections = re.split(r"^<!-- section: (\w+) -->\n", text, flags=re.MULTILINE)
    names = sections[1::2]
    assert names == ["boards", *(b.name for b in measurements.BENCHMARKS)]
    for name, body in zip(names, sections[2::2]):
        measured = re.search(r"^Measured \d{4}-\d\d-\d\d \d\d:\d\d UTC at commit \w+", body,
                             flags=re.MULTILINE)
        if name == "boards":
            assert ("| board | clock |" in body) != (measurements.NOT_MEASURED in body), name
        else:
            assert bool(measured) != (measurements.NOT_MEASURED in body), name
            if measured:
                assert "\n```\n" in body, name


def test_a_benchmark_that_cannot_run_is_not_measured():
    measurements = _script()
    benchmark = measurements.Benchmark("x", "X", "scene_throughput.py",
                                       needs=("no-such-tool-fliss",))
    outcome = measurements.run(benchmark, head="abc")
    assert outcome.status is None and outcome.reason == "no-such-tool-fliss not installed"
    section = measurements.section(benchmark, outcome)
    assert f"**{measurements.NOT_MEASURED}**: no-such-tool-fliss not installed" in section
    assert "```" not in section


# What a measurement history reads like: the load of the machine it was taken on, its date.
HISTORY = re.compile(r"load average|at a load of|\bload of about|shared (2-core |two-core )?"
                     r"machine|quiet machine|idle machine|on the development machine|"
                     r"\(20\d\d-\d\d", flags=re.IGNORECASE)


@pytest.mark.parametrize("page", [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))],
                         ids=lambda path: path.name)
def test_reference_pages_carry_no_measurement_history(page):
    if page == PAGE:
        return
    found = [f"{page.name}:{number}: {line.strip()}"
             for number, line in enumerate(page.read_text().splitlines(), 1)
             if HISTORY.search(line)]
    assert not found, "\n".join(found)


@pytest.mark.parametrize("page", [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
                                  *sorted((ROOT / "benchmarks").glob("*.py"))],
                         ids=lambda path: path.name)
def test_no_page_names_an_issue(page):
    # Readers see the docs and the benchmarks' texts (the measurements page quotes them), never
    # the project's issue tracker: "issue 44" tells them nothing
    found = [f"{page.name}:{number}: {line.strip()}"
             for number, line in enumerate(page.read_text().splitlines(), 1)
             if re.search(r"\bissues? \d+", line, flags=re.IGNORECASE)]
    assert not found, "\n".join(found)
