"""``fliss board``: run the virtual board (:mod:`fliss.host.virtual`) until Ctrl-C, and print
the path of its pty."""

import logging
import signal
import sys
import time

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...sim.boards.loopback import JUMPER_DELAY_S
from ...sim.boards.noisy_line import NoisyLine, add_line_arguments, describe, faults_from_args
from ...sim.boards.options import add_scene_arguments, rate_hz
from ..errors import UserError
from ..units import parse_baud
from ..virtual import ENGINES, SIMULATORS, VirtualBoard


__all__ = ["register", "run_board"]


logger = logging.getLogger(__name__)


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "board", formatter_class=formatter,
        help="run the virtual board: the real gateware in a simulator, behind a pty",
        description="Generates the Verilog of the FLISS top level, builds it once for the "
                    "engine (build/virtual-board/fast/, SIM/, SIM-fine/ or SIM-small/), runs it with the scene "
                    "simulator on its sensor pins in closed loop, and prints the path of a "
                    "pseudo-terminal carrying its UART (also linked as build/virtual-board/tty, "
                    "or tty-2, ... "
                    "while other boards run: it says which). Use that path "
                    "as --port of the other commands. Runs until Ctrl-C. The simulation runs "
                    "some hundred times slower than a real board: keep integration times "
                    "to a few ms and use a bin shift.")
    parser.add_argument("--sim", choices=SIMULATORS, default="verilator",
                        help="simulator")
    parser.add_argument("--engine", choices=ENGINES, default=None,
                        help="fast: the Verilated model in a C++ harness (Verilator only); "
                             "cocotb: the cocotb module (any simulator); default fast with "
                             "Verilator when a C++ compiler is installed, else cocotb")
    parser.add_argument("--baud", default="12M", help="UART baud rate of the gateware")
    add_scene_arguments(parser)
    parser.add_argument("--reset-after", type=int, default=None, metavar="PACKETS",
                        help="reset the gateware (a power cycle) once, after this many data "
                             "packets to the host; SIGUSR1 to this process resets it too")
    parser.add_argument("--fine-tdc", action="store_true",
                        help="build the top level with the fine TDC, its delay line driven from "
                             "the model (the on-chip oscillator, the internal loopback of the "
                             "trigger outputs' pads, and a jumper with --jumper: `fliss "
                             "selftest` and `fliss calibrate` run on it); cocotb engine only")
    parser.add_argument("--small", action="store_true",
                        help="build the top level with the iCEBreaker's options (histograms "
                             "only: no raw events, no aggressor emitter, no keyed mode), at "
                             f"the virtual board's {DEFAULT_CLOCK_HZ / 1e6:g} MHz; cocotb engine only")
    parser.add_argument("--jumper", choices=("laser", "aggressor"), default=None,
                        help="a jumper wire from the laser output or the aggressor's trigger "
                             f"to the photon input, {JUMPER_DELAY_S * 1e9:g} ns after the trigger's "
                             "clock edge: the "
                             "coarse TDC's pin, and with --fine-tdc the fine TDC's line "
                             "(`fliss selftest --jumper` runs on it); cocotb engine only")
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
    except ValueError as error:
        raise UserError(str(error)) from None
    if args.reset_after is not None and args.reset_after < 1:
        raise UserError(f"--reset-after must be at least 1, not {args.reset_after}")
    board = VirtualBoard(args.sim, engine=args.engine, baud=baud, target_m=args.target_m,
                         ambient_hz=ambient_hz, signal=args.signal,
                         aggressor_signal=args.aggressor_signal, seed=args.seed,
                         scene=args.scene, sensor=args.sensor, object_m=args.object_m,
                         reset_after=args.reset_after, fine_tdc=args.fine_tdc,
                         small=args.small, jumper=args.jumper)

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
    try:
        path = board.start()
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
        print("fliss: virtual board stopped", file=sys.stderr)
        return 0
    finally:
        if line is not None:
            line.close()
            print(f"fliss: noisy line: {describe(line)}", file=sys.stderr)
        board.stop()


def _what(board):
    # "verilator, fast engine"
    return f"{board.sim}, {board.engine} engine"


def _link(board):
    # " (link build/virtual-board/tty-2)": this board's own link to its pty, if it has one
    return "" if board.link is None else f" (link {board.link})"
