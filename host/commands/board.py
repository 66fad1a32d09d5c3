"""``fliss board``: run the virtual board (:mod:`fliss.host.virtual`) until Ctrl-C, and print
the path of its pty."""

import logging
import signal
import sys
import time

import math

from ...hdl.event import TDC_LSB_S, TIMESTAMP_BITS
from ...sim.boards.noisy_line import NoisyLine, add_line_arguments, describe, faults_from_args
from ...sim.boards.options import (add_build_arguments, add_scene_arguments, detector_from_args,
                                  detector_note, rate_hz)
from ...sim.scene import LINE_PIXELS
from ..errors import UserError
from ..units import parse_baud
from ..virtual import ENGINES, SIMULATORS, VirtualBoard


__all__ = ["register", "run_board", "column_note"]

#: Below this share of laser cycles in which the column keeps the wall's echo, say so.
KEPT_ECHOES = 0.05

#: The demo's light for the line scene, with which its depth frames are right.
DEMO_LIGHT = "--signal 0.02 --aggressor-signal 0.02 --ambient 10kHz"


logger = logging.getLogger(__name__)


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "board", formatter_class=formatter,
        help="run the virtual board: the real gateware in a simulator, behind a pty",
        description="Generates the Verilog of the FLISS top level, builds it once for the "
                    "engine, gateware and options into the per-user cache "
                    "($FLISS_CACHE_DIR, else $XDG_CACHE_HOME/fliss or ~/.cache/fliss: "
                    "virtual-board/fast-KEY/, SIM-KEY/, SIM-fine-KEY/ or SIM-small-KEY/; it "
                    "says so before a build of minutes), runs it with the scene "
                    "simulator on its sensor pins in closed loop, and prints the path of a "
                    "pseudo-terminal carrying its UART (also linked as virtual-board/tty of the "
                    "cache, or tty-2, ... while other boards run: it says which). Use that path "
                    "as --port of the other commands. Runs until Ctrl-C. The simulation runs "
                    "some hundred times slower than a real board: keep integration times "
                    "to a few ms and use a bin shift.")
    parser.add_argument("--sim", choices=SIMULATORS, default="verilator",
                        help="simulator")
    parser.add_argument("--engine", choices=ENGINES, default=None,
                        help="fast: the Verilated model in a C++ harness (Verilator only); "
                             "cocotb: the cocotb module (any simulator); default fast with "
                             "Verilator when a C++ compiler is installed, else cocotb")
    add_scene_arguments(parser)
    parser.add_argument("--reset-after", type=int, default=None, metavar="PACKETS",
                        help="reset the gateware (a power cycle) once, after this many data "
                             "packets to the host; SIGUSR1 to this process resets it too")
    add_build_arguments(parser, where="; on the cocotb engine, which it chooses by default")
    add_line_arguments(parser)
    parser.set_defaults(run=run_board)


def run_board(args):
    try:
        baud = parse_baud(args.baud)
        faults = faults_from_args(args)
    except ValueError as error:
        raise UserError(str(error)) from None
    try:
        ambient_hz = rate_hz(args.ambient)
        detector = detector_from_args(args)
    except ValueError as error:
        raise UserError(str(error)) from None
    if args.reset_after is not None and args.reset_after < 1:
        raise UserError(f"--reset-after must be at least 1, not {args.reset_after}")
    board = VirtualBoard(args.sim, engine=args.engine, baud=baud, target_m=args.target_m,
                         ambient_hz=ambient_hz, signal=args.signal,
                         aggressor_signal=args.aggressor_signal, seed=args.seed,
                         scene=args.scene, sensor=args.sensor, object_m=args.object_m,
                         reset_after=args.reset_after, fine_tdc=args.fine_tdc,
                         small=args.small, jumper=args.jumper, detector=detector)

    for note in (column_note(args.scene, args.sensor, args.aggressor_signal, ambient_hz),
                 detector_note(args, detector)):
        if note:
            print(f"fliss: note: {note}", file=sys.stderr, flush=True)

    def terminate(number, frame):
        raise KeyboardInterrupt

    def reset(number, frame):
        if board.running:
            logger.warning("resetting the virtual board (SIGUSR1)")
            board.reset()

    # `kill` (as a script does to a board in the background) and a closed terminal stop the
    # board as cleanly as Ctrl-C.
    signal.signal(signal.SIGTERM, terminate)
    signal.signal(signal.SIGHUP, terminate)
    signal.signal(signal.SIGUSR1, reset)
    line = None
    started = False
    try:
        if not board.built:
            print(f"fliss: building the virtual board ({_what(board)}, {baud} baud), once for "
                  f"this gateware and these options: some minutes; cached in {board.folder}; "
                  f"Ctrl-C stops it", file=sys.stderr, flush=True)
        path = board.start()
        started = True
        for name in board.stale_links:
            print(f"fliss: removed {board.root / name}, the link of a board that was killed",
                  file=sys.stderr)
        if faults is not None:
            line = NoisyLine(path, to_host=faults[0], to_board=faults[1], seed=args.line_seed)
            print(line.open(), flush=True)
            print(f"fliss: virtual board ({_what(board)}, {baud} baud) on {path}{_link(board)}, "
                  f"behind a noisy line on {line.path}; Ctrl-C stops it",
                  file=sys.stderr, flush=True)
        else:
            print(path, flush=True)
            print(f"fliss: virtual board ({_what(board)}, {baud} baud) on {path}{_link(board)}; "
                  f"Ctrl-C stops it", file=sys.stderr, flush=True)
        last = time.monotonic()
        previous = {}
        while True:
            time.sleep(0.5)
            if not board.running:
                raise UserError(f"the {args.sim} simulation stopped: {board.last_log_line()}")
            if line is not None and not line.running:
                raise UserError(f"the noisy line stopped: {line.error}")
            if time.monotonic() - last >= 10:
                last = time.monotonic()
                stats = board.stats()
                if stats and previous and stats["wall_s"] > previous["wall_s"]:
                    wall_s = stats["wall_s"] - previous["wall_s"]
                    logger.info("%.0f clock cycles/s simulated, %.0f bytes/s to the host, "
                                "%d events", (stats["cycles"] - previous["cycles"]) / wall_s,
                                (stats["bytes_to_host"] - previous["bytes_to_host"]) / wall_s,
                                stats["events"] - previous["events"])
                previous = stats
    except KeyboardInterrupt:
        if not started:
            print("fliss: interrupted before the virtual board started (its build, if one was "
                  "under way, is left unfinished and made again next time)", file=sys.stderr)
            return 130
        print("fliss: virtual board stopped", file=sys.stderr)
        return 0
    finally:
        if line is not None:
            line.close()
            print(f"fliss: noisy line: {describe(line)}", file=sys.stderr)
        board.stop()


def column_note(scene, sensor, aggressor_signal, ambient_hz):
    """A note for a line scene seen by the column sensor in light too bright for depth frames,
    or None. The column's one TDC keeps the last photon of a laser cycle; every photon of the
    aggressor (``aggressor_signal`` a pixel and pulse) and of the ambient light (``ambient_hz``
    a pixel) in the TDC window can come after the wall's echo and replace it, so the echo is
    kept in about ``exp(-n)`` of the cycles, ``n`` being those photons of the line's pixels in
    one window (an estimate: the aggressor's photons before the echo do not count)."""
    if scene != "line" or sensor != "column":
        return None
    window_s = (1 << TIMESTAMP_BITS) * TDC_LSB_S
    photons = LINE_PIXELS * (aggressor_signal + ambient_hz * window_s)
    kept = math.exp(-photons)
    if kept >= KEPT_ECHOES:
        return None
    return (f"about {photons:.1f} photons of aggressor and ambient light reach the column in a "
            f"laser cycle's {window_s * 1e9:.1f} ns window and it keeps the last: the wall's "
            f"echo in about {100 * kept:.1g} % of cycles; depth frames will show nothing or "
            f"ghosts near the end of the range. The demo's light ({DEMO_LIGHT}) or "
            f"--sensor per_pixel give the scene's depths (with fliss config --depth-filter 2, "
            f"as the demo)")


def _what(board):
    # "verilator, fast engine"
    return f"{board.sim}, {board.engine} engine"


def _link(board):
    # " (link ~/.cache/fliss/virtual-board/tty-2)": this board's own link to its pty, if any
    return "" if board.link is None else f" (link {board.link})"
