"""``fliss demo``: FLISS at work on the virtual board, with no hardware.

The real top-level gateware runs in a simulator behind a pseudo-terminal (``fliss board``); the
scene simulator feeds its sensor pins with the echo of a target 4 m away and with the photons of
an aggressor whose trigger is the gateware's own aggressor output, 75 ns after the victim and at
the victim's effective PRF (:func:`effective_period`). The demo then drives it with the ordinary
commands (``config``, ``capture``, ``analyze``, ``plot``), first with FLISS off and then with the
masked delay source (Wm = 6), and prints what changed.
Then the imager: a second virtual board sees a line scene (the paper's column of 60 pixels, a
wall at 4 m with an object at 2.5 m in front of pixels 20 to 39) lit by a flash aggressor, and
the board sends a depth frame per integration; with FLISS off the aggressor plants ghost depths,
with FLISS on the profile is the scene's. Last, ``fliss attack`` shows an attacker that predicts
the ``mseq`` and ``masked`` delays and makes a ghost target, and fails against the ``keyed``
source.
"""

import math
import shlex
import time
from dataclasses import dataclass
from functools import partial

import numpy as np

from amaranth.sim import Simulator

from ...hdl.clock import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles
from ...hdl.delay.core import DelayCore
from ...sim.models.delay import DelayMode, mean_delay
from ...sim.models import scheduler as scheduler_model
from ...sim.models.scheduler import prf_rows
from ..errors import UserError
from ..paths import check_output_dir
from ..settings import duration_s
from ..units import format_frequency


#: Speed of light, m/s.
C_M_S = 299_792_458.0


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "demo", formatter_class=formatter, help="show FLISS at work on the virtual board",
        description="Starts the virtual board (the real gateware in a simulator behind a pty), "
                    "captures histograms with an aggressor running, first with FLISS off and "
                    "then on (masked delays, Wm = 6), prints both peak tables and the "
                    "suppression, and writes a PNG of the two histograms.")
    parser.add_argument("--sim", choices=["verilator", "icarus"], default="verilator",
                        help="simulator of the virtual board")
    parser.add_argument("--out", default="build/demo", metavar="DIR",
                        help="output folder; the demo replaces its own files there "
                             "(fliss-off.h5, fliss-on.h5, demo.png, imager-off.h5, imager-on.h5, "
                             "imager.png, attack.txt, attack.png)")
    parser.add_argument("--acquisitions", type=int, default=2,
                        help="histograms per setting")
    parser.add_argument("--integration", default="2ms", metavar="TIME",
                        help="integration time per histogram (simulated time)")
    parser.add_argument("--target-m", type=float, default=4.0, metavar="M",
                        help="distance of the victim's target (and of the imager's wall)")
    parser.add_argument("--depth-frames", type=int, default=3, metavar="N",
                        help="depth frames per setting in the imager part")
    parser.add_argument("--trace", action="store_true",
                        help="instead: print a pulse scheduler trace from the gateware, checked "
                             "against the reference model (about a second, no simulator needed)")
    parser.set_defaults(run=run)


def effective_period(period, mask_width=None):
    """The victim's mean pulse interval in whole clock cycles, its nominal period ``T`` plus its
    mean delay (the clock frequency over it is its effective PRF): ``T`` with FLISS off
    (``mask_width`` None), ``T + E[R]`` with masked delays of ``mask_width`` bits. The demo's
    aggressor runs at this period."""
    if mask_width is None:
        return period
    return round(period + mean_delay(DelayMode.MASKED, mask_width=mask_width))


def trace_gateware(settings, cycles, clock_hz=DEFAULT_CLOCK_HZ):
    """Run the delay core in Amaranth's simulator; return its pulses and laser rising edges."""
    dut = DelayCore(clock_hz=clock_hz)
    pulses, edges = [], []

    async def testbench(ctx):
        for name in ("mode", "length", "mask_width", "seed", "period", "grid", "pulse_width"):
            ctx.set(getattr(dut.settings, name), getattr(settings, name))
        await ctx.tick()
        ctx.set(dut.enable, 1)
        for cycle in range(1, cycles):
            if ctx.get(dut.fire):
                pulses.append((cycle, ctx.get(dut.fire_delay), settings.pulse_width,
                               ctx.get(dut.pulse_index)))
            if ctx.get(dut.tdc_start):
                edges.append(cycle)
            await ctx.tick()

    sim = Simulator(dut)
    sim.add_clock(1 / clock_hz)
    sim.add_testbench(testbench)
    sim.run()
    return pulses, edges


#: The options of the demo (``dest``), which --trace does not take.
_DEMO_OPTIONS = {"sim", "out", "acquisitions", "integration", "target_m", "depth_frames"}


def run_trace(pulses=12):
    period = period_cycles(DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ)
    settings = scheduler_model.Settings(mode=DelayMode.MSEQ, length=4, seed=1, period=period,
                                        pulse_width=2).check()
    cycles = (period + 15) * (pulses + 1)
    fired, edges = trace_gateware(settings, cycles)
    expected = scheduler_model.simulate(settings, cycles - 1, enable=1)
    print("Gateware trace (mseq, L = 4, seed 1): each pulse T + R cycles after the previous")
    print(f"  {'pulse':>5} {'delay R':>8} {'laser/TDC start':>16} {'interval':>9}")
    previous = None
    for (_, delay, _, index), edge in list(zip(fired, edges))[:pulses]:
        interval = "" if previous is None else f"{edge - previous}"
        print(f"  {index:>5} {delay:>8} {edge:>16} {interval:>9}")
        previous = edge
    same = fired == expected[:len(fired)] and \
        edges == [fire + scheduler_model.LATENCY for fire, *_ in fired]
    print(f"Gateware and reference model agree bit for bit: {'yes' if same else 'NO'}")
    return 0 if same else 1


def _step(fliss, title, argv):
    print(f"\n== {title}\n$ fliss {' '.join(shlex.quote(a) for a in argv)}", flush=True)
    code = fliss(argv)
    if code:
        raise UserError(f"the demo stopped: `fliss {argv[0]}` failed")


def run(args):
    if args.trace:
        typed = sorted(set(getattr(args, "given", ())) & _DEMO_OPTIONS)
        if typed:
            raise UserError(f"--{typed[0].replace('_', '-')} is an option of the demo on the "
                            f"virtual board, not of --trace (a fixed trace of 12 pulses)")
        return run_trace()
    if args.acquisitions < 1:
        raise UserError(f"--acquisitions must be at least 1, not {args.acquisitions}")
    if args.depth_frames < 1:
        raise UserError(f"--depth-frames must be at least 1, not {args.depth_frames}")
    if not (math.isfinite(args.target_m) and args.target_m > 0):
        raise UserError(f"--target-m must be a positive distance in metres, not {args.target_m:g}")
    duration_s(args.integration, f"--integration {args.integration}")    # a time with a unit
    step = partial(_step, args.fliss)
    from ..virtual import start_virtual_board
    from ..fileformat import read_capture
    from ..analysis import analyze

    clock_hz, prf_hz = DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ
    period = period_cycles(clock_hz, prf_hz)
    tof_s = 2 * args.target_m / C_M_S
    out = check_output_dir(args.out, flag="--out")
    # As on the paper's bench, the aggressor runs at the victim's effective PRF.
    masked_period = effective_period(period, mask_width=6)
    print(f"FLISS demo: victim at {format_frequency(prf_hz)} ({period} cycles of "
          f"{format_frequency(clock_hz)}), target {args.target_m:g} m (ToF "
          f"{tof_s * 1e9:.2f} ns), aggressor 75 ns after the victim at the victim's effective "
          f"PRF ({format_frequency(clock_hz / period)} with FLISS off, "
          f"{format_frequency(clock_hz / masked_period)} with masked delays).")
    print("Effective PRF of the victim, complete m-sequences (paper, Table 2): " + ", ".join(
        f"L={s['length']}: {format_frequency(closed)}"
        for _, s, _, _, closed, _ in prf_rows(clock_hz, period, {"length": [3, 4, 5, 6, 8]})))
    started = time.monotonic()
    print(f"\nStarting the virtual board: FlissTop in {args.sim}, the scene simulator on its "
          f"sensor pins (the first run builds the simulation, about a minute)...", flush=True)
    with start_virtual_board(args.sim, target_m=args.target_m, signal=0.2,
                             aggressor_signal=0.2, seed=1) as port:
        print(f"virtual board on {port}")
        common = ["--port", port]
        capture = ["--readout", "histogram", "--integration", args.integration,
                   "--acquisitions", str(args.acquisitions)]
        files = {}
        for label, mode, aggressor_period in (
                ("FLISS off", ["--mode", "off"], effective_period(period)),
                ("FLISS on, masked delays, Wm = 6", ["--mode", "masked", "--mask-width", "6",
                                                     "--seed", "0xACE1"], masked_period)):
            step(f"{label}: configure", ["config", *common, *mode, "--aggressor", "on",
                                          "--aggressor-period-cycles", str(aggressor_period),
                                          "--bin-shift", "3", "--integration", args.integration])
            name = "fliss-off.h5" if "off" in label else "fliss-on.h5"
            files[label] = out / name
            # the demo's own files in its folder: a second run replaces them
            step(f"{label}: capture", ["capture", *common, *capture, "-o", str(files[label]),
                                        "--overwrite"])
    paths = [str(path) for path in files.values()]
    step("Peaks and suppression", ["analyze", *paths, "--victim-tof", f"{tof_s * 1e9:.3f}ns"])
    png = out / "demo.png"
    step("Histograms", ["plot", *paths, "-o", str(png), "--overwrite",
                        "--victim-tof", f"{tof_s * 1e9:.3f}ns"])
    imager = run_imager(args, out, period, masked_period)
    # An attacker that predicts the delays (docs/security.md): a few seconds of model time.
    step("An attacker that predicts the delays (mseq, masked) and one it cannot (keyed)",
          ["attack", "--sources", "off,mseq,masked,keyed", "--lengths", "8",
           "--mask-widths", "6", "--pulses", "6000", "--scene-pulses", "6000",
           "--acquisition-pulses", "3000", "--no-unknown-taps",
           "--table", str(out / "attack.txt"), "--figure", str(out / "attack.png"),
           "--overwrite"])

    print("\n== Summary")
    for label, path in files.items():
        data = read_capture(path)
        histogram = data.total_histogram()
        result = analyze(histogram, data.bin_s, configuration=data.configuration,
                         victim_s=tof_s, shift=data.shift).suppression
        if result is None:
            print(f"  {label:<32} no victim peak found")
            continue
        relation = ">=" if result.limited else "="
        print(f"  {label:<32} victim peak {result.victim.height:7.1f} counts at "
              f"{result.victim.position_s * 1e9:6.2f} ns, S {relation} {result.s_db:5.1f} dB")
    for line in imager.lines:
        print(f"  imager, {line}")
    print(f"  plots: {png}, {imager.png}   ({time.monotonic() - started:.0f} s)")
    return 0


@dataclass(frozen=True)
class ImagerResult:
    """What the imager part found: the summary lines and the figure."""
    lines: list
    png: object


def run_imager(args, out, period, masked_period):
    """The imager part of the demo: depth frames of the line scene, FLISS off and on, with a
    flash aggressor, through ``fliss config``, ``capture --readout depth`` and ``analyze``; the
    two depth profiles drawn beside the scene's."""
    step = partial(_step, args.fliss)
    from ..virtual import start_virtual_board
    from ..fileformat import read_capture
    from ..imager.demo import compare_profiles, draw_profiles, summary_lines
    from ...sim.scene import line_pixels

    line = line_pixels(wall_m=args.target_m)
    truth = np.asarray(line.distance_m, dtype=float)
    print(f"\n== The imager: a line of {len(truth)} pixels (wall at {args.target_m:g} m, an object "
          f"at 2.5 m before pixels 20-39), a flash aggressor lighting every pixel; one depth "
          f"frame per integration, made on the board", flush=True)
    # Weak light (the column's TDC keeps one photon a laser cycle: the last pixel to fire)
    with start_virtual_board(args.sim, scene="line", target_m=args.target_m, signal=0.02,
                             aggressor_signal=0.02, ambient_hz=1e4, seed=1) as port:
        print(f"virtual board (line scene) on {port}")
        common = ["--port", port]
        files = {}
        for label, mode, aggressor_period in (
                ("FLISS off", ["--mode", "off"], period),
                ("FLISS on", ["--mode", "masked", "--mask-width", "6", "--seed", "0xACE1"],
                 masked_period)):
            step(f"Imager, {label}: configure",
                  ["config", *common, *mode, "--aggressor", "on", "--aggressor-period-cycles",
                   str(aggressor_period), "--pixels", "64", "--bin-shift", "6",
                   "--depth-filter", "2", "--depth-threshold", "4", "--integration", "2ms"])
            files[label] = out / ("imager-off.h5" if "off" in label else "imager-on.h5")
            step(f"Imager, {label}: capture depth frames",
                  ["capture", *common, "--readout", "depth", "--acquisitions",
                   str(args.depth_frames), "-o", str(files[label]), "--overwrite"])
    step("Imager: per-pixel table (FLISS on)", ["analyze", str(files["FLISS on"])])
    depths = []
    for path in files.values():
        capture = read_capture(path)
        # (64 pixels histogrammed; the line has the first 60)
        depths.append(np.asarray(capture.depth["depth_m"], dtype=float)[capture.complete][
            :, :len(truth)])
    comparison = compare_profiles(*depths, truth, np.arange(len(truth)))
    png = out / "imager.png"
    draw_profiles(comparison, png, title="Depth profiles of the line scene with a flash "
                                         "aggressor")
    lines = summary_lines(comparison)
    print("\n".join(lines) + f"\nplot: {png}")
    return ImagerResult(lines, png)
