"""Speed of the virtual board: clock cycles simulated per second of wall time (and per second
of the simulation's CPU time: on a shared machine, the speed on one core of its own).

Prints, beside the figures measured before the fast harness (:data:`BEFORE`, the cocotb
virtual board on the shared 2-core development machine):

* ``raw``: Verilator's own speed on the top level with nothing attached, in the fast harness
  (:mod:`fliss.sim.boards.harness`): idle, and acquiring at 1 MHz with the aggressor on (no
  sensor events); ``--threads 2`` builds and measures a two-threaded model too;
* per engine (``fast``, ``cocotb``) and scene (``single``: the paper's one pixel; ``line``: 60
  pixels, column sensor): the start-up time of the board (build cached) and its speed while it
  makes 10 ms histograms at 1 MHz PRF with the aggressor on, as its statistics report them
  (the time the scene simulator took is ``scene``).

With ``--detectors default,every`` each board runs also with every effect of the detector on
(``every``: PDP 50 %, dark counts with 5 % hot pixels, a 20 % diffusion tail, afterpulsing 2 %
with 20 and 200 ns, crosstalk 1 % and 0.2 %: ``benchmarks/detector_throughput.py``'s), as
``fliss board``'s detector options would set it.

Usage: ``python benchmarks/virtual_board.py [--seconds S] [--engines fast,cocotb]
[--scenes single,line] [--detectors default,every] [--threads 1,2] [--skip-raw]``
"""

import argparse
import time

from fliss.hdl.protocol import PacketType
from fliss.hdl.protocol import registers_layout
from fliss.hdl.registers import BY_NAME
from fliss.protocol import PacketEncoder, pack
from fliss.host.client import BoardClient
from fliss.host.virtual import VIRTUAL_BAUD, VirtualBoard, board_folder, build_root

from detector_throughput import every_effect


#: Before the fast harness: the cocotb virtual board (Verilator) on the shared development
#: machine at load average 1: clock cycles per second of a 10 ms histogram acquisition (15 s),
#: start-up in seconds with the build cached (then about 9 s of it made the Verilog again to
#: compare it with the build; 29 to 53 s at load average 7 to 10).
BEFORE = {
    ("cocotb", "single"): {"cycles_per_s": 109_000, "startup_s": 10.6},
    ("cocotb", "line"): {"cycles_per_s": 92_000, "startup_s": 10.5},
}

#: The paper's set-up: 1 MHz PRF (the reset period), the aggressor on, 10 ms histograms.
SETTINGS = {"aggressor": 1}


def raw(threads, cycles=2_000_000):
    """Verilator on the top level in the harness, nothing attached: cycles/s idle, and
    acquiring (START through the UART)."""
    from fliss.sim.boards import harness
    folder = board_folder(build_root(), "fast", "verilator")
    if threads != 1:
        folder = folder.with_name(f"{folder.name}-threads-{threads}")
    library = harness.build(folder, baud=VIRTUAL_BAUD, threads=threads)
    board = harness.Harness(library, 80e6 / VIRTUAL_BAUD)
    figures = {}
    figures["idle"] = _timed(board.run, cycles)
    encoder = PacketEncoder()
    for name, value in SETTINGS.items():
        board.write(encoder.frame(PacketType.WRITE, pack(
            registers_layout(1), address=BY_NAME[name].address, values=[value])))
    board.write(encoder.frame(PacketType.START))
    board.run(board.cycle + 20_000)
    figures["acquiring"] = _timed(board.run, board.cycle + cycles)
    assert board.running, "the board did not start"
    board.close()
    return figures


def _timed(run, until):
    """Clock cycles per second of wall time and of CPU time of ``run(until)``."""
    wall, cpu, cycles = time.perf_counter(), time.process_time(), -run.__self__.cycle
    run(until)
    cycles += run.__self__.cycle
    return cycles / (time.perf_counter() - wall), cycles / (time.process_time() - cpu)


def on_board(engine, scene, seconds, detector=None):
    """Start-up time and clock cycles/s of a virtual board making histograms."""
    began = time.perf_counter()
    board = VirtualBoard("verilator", engine=engine, scene=scene, seed=1, detector=detector)
    path = board.start()
    startup_s = time.perf_counter() - began
    try:
        client = BoardClient(path, baud=VIRTUAL_BAUD)
        client.write_registers(SETTINGS)
        client.start()
        first = _stats_after(board, 1.0)
        time.sleep(seconds)
        last = _stats_after(board, first["wall_s"] + seconds)
        client.serial.close()
    finally:
        board.stop()
    wall_s = last["wall_s"] - first["wall_s"]
    cycles = last["cycles"] - first["cycles"]
    cpu_s = last["cpu_s"] - first["cpu_s"]
    return {"startup_s": startup_s, "cycles_per_s": cycles / wall_s,
            "cycles_per_cpu_s": cycles / cpu_s,
            "scene_share": (last["scene_s"] - first["scene_s"]) / wall_s}


def _stats_after(board, wall_s):
    while True:
        stats = board.stats()
        if stats and stats["wall_s"] >= wall_s:
            return stats
        time.sleep(0.05)


def _figure(value, digits=3):
    return "-" if value is None else f"{value:.{digits}g}"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0,
                        help="wall time measured per board")
    parser.add_argument("--engines", default="fast,cocotb")
    parser.add_argument("--scenes", default="single,line")
    parser.add_argument("--detectors", default="default",
                        help="default, every (every effect of the detector on), or both")
    parser.add_argument("--threads", default="1", help="Verilator threads of the raw figures")
    parser.add_argument("--skip-raw", action="store_true")
    args = parser.parse_args(argv)
    if not args.skip_raw:
        print("Verilator on the top level, nothing attached (clock cycles/s):")
        for threads in [int(value) for value in args.threads.split(",")]:
            figures = raw(threads)
            print(f"  {threads} thread(s): idle {figures['idle'][0]:.3g} (per CPU second "
                  f"{figures['idle'][1]:.3g}), acquiring {figures['acquiring'][0]:.3g} "
                  f"({figures['acquiring'][1]:.3g})", flush=True)
    print("\nThe virtual board making 10 ms histograms at 1 MHz, aggressor on:")
    print(f"{'engine':8} {'scene':7} {'detector':8} {'cycles/s':>10} {'per CPU s':>10} "
          f"{'before':>10} {'start-up s':>11} {'before':>7} {'scene share':>12}")
    for engine in args.engines.split(","):
        for scene, kind in [(scene, kind) for scene in args.scenes.split(",")
                            for kind in args.detectors.split(",")]:
            now = on_board(engine, scene, args.seconds,
                           detector=every_effect(False) if kind == "every" else None)
            before = BEFORE.get(("cocotb", scene), {}) if kind == "default" else {}
            print(f"{engine:8} {scene:7} {kind:8} {now['cycles_per_s']:>10.3g} "
                  f"{now['cycles_per_cpu_s']:>10.3g} {_figure(before.get('cycles_per_s')):>10} "
                  f"{now['startup_s']:>11.1f} "
                  f"{_figure(before.get('startup_s'), 2):>7} {now['scene_share']:>12.0%}",
                  flush=True)


if __name__ == "__main__":
    raise SystemExit(main())
