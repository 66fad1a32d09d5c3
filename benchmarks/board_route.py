"""Routing time and Fmax of the ULX3S build over placement seeds: the build's nextpnr options
beside the old ones (nextpnr's default router, router1) as the baseline.

Synthesizes the design once with the board build's Yosys script (``python -m fliss.boards.build``
does the same), then runs nextpnr on that netlist for each seed and each setting, one run at a
time, and prints per run the routing time (nextpnr's own figures for its routers), the run's
wall-clock time (packing, placement, routing, timing analysis), the Fmax of every clock and the
LUT/FF/block RAM count; then the range of each setting over the seeds. A run that passes
``--timeout`` is stopped and printed as such: its Fmax is unknown.

Settings:

* ``baseline``: the options the build had before, nextpnr's defaults (HeAP placer, router1);
* ``build``: the options the build uses now, ``FlissULX3SPlatform.nextpnr_opts``.

Defaults: the ULX3S's design with the fine TDC built for 100 MHz (the Fmax goal), seeds 1 to 5.
``--clock 80e6 --design fliss.boards:fliss_top`` is the build that ``make test-boards`` checks
at the board's clock without the fine TDC.

Usage: python benchmarks/board_route.py [--seeds N] [--clock HZ] [--design MODULE:FACTORY]
       [--setting baseline|build ...] [--timeout S] [--build-dir DIR]
"""

import argparse
import json
import re
import resource
import subprocess
import sys
import time
from pathlib import Path

from fliss.boards import BoardTop, platform_class
from fliss.boards.build import (BOARD_DESIGN, BuildResult, ToolchainError, _parse_report,
                                load_design, toolchain_env)


BOARD = "ulx3s"
NAME = f"fliss_{BOARD}"


#: Settings besides the build's own: name -> nextpnr options beyond the device and the report.
CANDIDATES = {
    "baseline":    [],                                     # nextpnr's defaults: HeAP, router1
    "router2":     ["--router", "router2"],
    "router2-tmg": ["--router", "router2", "--tmg-ripup"],
}


def settings(platform):
    """Setting name -> nextpnr options: :data:`CANDIDATES` and ``build``, the board's own
    (``FlissULX3SPlatform.nextpnr_opts``)."""
    return {**CANDIDATES, "build": list(platform.nextpnr_opts)}


def synthesize(platform, design, folder, env):
    """The board build's files in ``folder`` and its Yosys run; returns the nextpnr command of
    its script (device, package, JSON, LPF), without its outputs."""
    plan = platform.prepare(BoardTop(design), name=NAME, nextpnr_opts=[],
                            synth_opts=list(platform.synth_opts))
    plan.extract(str(folder))
    start = time.monotonic()
    process = subprocess.run([env["YOSYS"], "-q", "-l", f"{NAME}.rpt", f"{NAME}.ys"],
                             cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    if process.returncode != 0:
        raise ToolchainError(f"Yosys failed; log in {folder / (NAME + '.rpt')}")
    print(f"synthesized in {time.monotonic() - start:.0f} s ({folder})", flush=True)
    script = (folder / f"build_{NAME}.sh").read_text()
    line = next(line for line in script.splitlines() if line.startswith('"$NEXTPNR_ECP5"'))
    words = line.split()[1:]
    device = []
    for option in ("--85k", "--25k", "--45k", "--12k", "--um5g-85k"):
        if option in words:
            device.append(option)
    for option in ("--package", "--speed", "--json", "--lpf"):
        if option in words:
            device += [option, words[words.index(option) + 1]]
    # (the build script's own options, the board's nextpnr_opts among them, are left out: the
    # settings give them)
    return [env["NEXTPNR_ECP5"], "--timing-allow-fail", *device]


def _children_cpu():
    # CPU seconds of the finished child processes: on a shared machine, the wall-clock time
    # also counts the other processes' share.
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _route_seconds(log):
    # nextpnr's routers print "Router1 time 123.45s" or "Router2 time 12.34s" when they finish
    # (router2 hands its result to router1, which checks it): their sum is the routing phase.
    times = [float(value) for value in re.findall(r"Router[12] time ([\d.]+)s", log)]
    return sum(times) if times else None


def run(command, folder, tag, seed, options, timeout, clock_hz):
    """One nextpnr run; returns a dict of its figures (``stopped`` when it hit ``timeout``)."""
    log_name, report_name = f"{tag}-seed{seed}.log", f"{tag}-seed{seed}.report.json"
    argv = ["nice", "-n", "5", *command, "--quiet", "--log", log_name, "--report", report_name,
            "--seed", str(seed), *options]
    start, cpu = time.monotonic(), _children_cpu()
    try:
        process = subprocess.run(argv, cwd=folder, stdout=subprocess.PIPE,
                                 stderr=subprocess.STDOUT, timeout=timeout)
    except subprocess.TimeoutExpired:
        log = folder / log_name
        routing = log.exists() and "Info: Routing.." in log.read_text(errors="replace")
        return {"stopped": True, "total_s": time.monotonic() - start,
                "cpu_s": _children_cpu() - cpu, "phase": "routing" if routing else "placing"}
    total, cpu = time.monotonic() - start, _children_cpu() - cpu
    if process.returncode != 0:
        raise ToolchainError(f"nextpnr failed (status {process.returncode}); "
                             f"log in {folder / log_name}")
    result = BuildResult(board=BOARD, clock_hz=clock_hz, build_dir=folder, bitstream=None)
    _parse_report(result, json.loads((folder / report_name).read_text()))
    log = (folder / log_name).read_text(errors="replace")
    return {"stopped": False, "total_s": total, "cpu_s": cpu, "route_s": _route_seconds(log),
            "result": result}


def _line(tag, seed, figures, timeout):
    if figures["stopped"]:
        return (f"  {tag:11} seed {seed}: stopped at {timeout:.0f} s while {figures['phase']}: "
                f"Fmax unknown")
    result = figures["result"]
    clocks = "  ".join(
        f"{'design' if clock == result.design_clock else clock} "
        f"{result.fmax_mhz[clock]:6.2f}" for clock in result.fmax_mhz)
    used = "  ".join(f"{label} {result.utilisation[label][0]}"
                     for label in ("LUT", "FF", "BRAM") if label in result.utilisation)
    route = "?" if figures["route_s"] is None else f"{figures['route_s']:5.0f}"
    return (f"  {tag:11} seed {seed}: route {route} s  total {figures['total_s']:5.0f} s  "
            f"(CPU {figures['cpu_s']:5.0f} s)  Fmax MHz: {clocks}  "
            f"{'met' if result.timing_met else 'FAILS'} at {result.clock_hz / 1e6:.2f} MHz  "
            f"{used}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--seeds", type=int, default=5, help="placement seeds 1 to N")
    parser.add_argument("--clock", type=float, default=100e6, help="design clock, Hz")
    parser.add_argument("--design", default=BOARD_DESIGN[BOARD], metavar="MODULE:FACTORY",
                        help="design factory")
    parser.add_argument("--setting", action="append", choices=(*CANDIDATES, "build"),
                        help="settings to run (repeat; default: baseline and build)")
    parser.add_argument("--timeout", type=float, default=1800,
                        help="seconds after which a nextpnr run is stopped")
    parser.add_argument("--build-dir", type=Path, default=Path("build", "board_route"),
                        metavar="DIR", help="folder of the synthesis and the nextpnr logs")
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds must be at least 1, not {args.seeds}")
    try:
        design = load_design(args.design)
        platform = platform_class(BOARD)(clock_hz=args.clock)
        env = toolchain_env(BOARD)
        folder = args.build_dir.resolve()
        folder.mkdir(parents=True, exist_ok=True)
        command = synthesize(platform, design, folder, env)
    except (ToolchainError, ValueError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    chosen = {tag: options for tag, options in settings(platform).items()
              if tag in (args.setting or ("baseline", "build"))}
    if "build" in chosen and any(options == chosen["build"] for tag, options in
                                 chosen.items() if tag != "build"):
        same = next(tag for tag, options in chosen.items()
                    if tag != "build" and options == chosen["build"])
        print(f"build: the same options as {same}; not run twice")
        del chosen["build"]
    print(f"{BOARD} {args.design} built for {platform.clock_hz / 1e6:g} MHz; settings: " +
          "; ".join(f"{tag} [{' '.join(options) or 'nextpnr defaults'}]"
                    for tag, options in chosen.items()), flush=True)
    figures = {tag: [] for tag in chosen}
    for seed in range(1, args.seeds + 1):
        for tag, options in chosen.items():
            try:
                measured = run(command, folder, tag, seed, options, args.timeout,
                               platform.clock_hz)
            except ToolchainError as error:
                print(f"error: {error}", file=sys.stderr)
                return 1
            figures[tag].append(measured)
            print(_line(tag, seed, measured, args.timeout), flush=True)
    for tag, runs in figures.items():
        done = [run_ for run_ in runs if not run_["stopped"]]
        stopped = len(runs) - len(done)
        if not done:
            print(f"  {tag}: every run stopped at {args.timeout:.0f} s")
            continue
        route = [run_["route_s"] for run_ in done if run_["route_s"] is not None]
        fmax = [run_["result"].fmax_mhz.get(run_["result"].design_clock, 0.0) for run_ in done]
        span = f"{min(route):.0f}-{max(route):.0f} s" if route else "unknown"
        print(f"  {tag}: route {span}, Fmax "
              f"{min(fmax):.2f}-{max(fmax):.2f} MHz over {len(done)} seeds"
              + (f"; {stopped} stopped at {args.timeout:.0f} s" if stopped else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main())
