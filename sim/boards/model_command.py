"""The command line of the Python model board: ``python -m fliss.sim.boards.model`` serves a
:class:`~fliss.sim.boards.model.ModelBoard` on a pty, with the scene, build and line options of
``fliss board`` by the same names, and prints its path."""

import argparse
import signal
import sys
import time

from .loopback import Loopback
from .model import model_board
from .noisy_line import NoisyLine, add_line_arguments, describe, faults_from_args
from .options import (add_build_arguments, add_scene_arguments, baud_rate, detector_from_args,
                      detector_note, rate_hz)
from ..scene import Scene, pixels_named


__all__ = ["build_parser", "main", "scene_from_args"]


def build_parser():
    """The command line of ``python -m fliss.sim.boards.model``: the scene, build and line
    options of ``fliss board``, by the same names."""
    parser = argparse.ArgumentParser(
        prog="python -m fliss.sim.boards.model",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
        description="Serve a Python model of a FLISS board on a pseudo-terminal and print its "
                    "path; stop with Ctrl-C.")
    add_scene_arguments(parser, seed=0)
    add_build_arguments(parser, where=" (its registers, modelled)")
    parser.add_argument("--reset-after", type=int, default=None, metavar="PACKETS",
                        help="reset the board (a power cycle) after this many data packets")
    add_line_arguments(parser)
    return parser


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        faults = faults_from_args(args)
    except ValueError as error:
        parser.exit(2, f"{parser.prog}: error: {error}\n")
    if args.reset_after is not None and args.reset_after < 1:
        parser.exit(2, f"{parser.prog}: error: --reset-after must be at least 1, not "
                       f"{args.reset_after}\n")
    try:
        scene = scene_from_args(args)
        build = _build_from_args(args)
    except ValueError as error:
        parser.exit(2, f"{parser.prog}: error: {error}\n")
    note = detector_note(args, scene.spad)
    if note:
        print(f"{parser.prog}: note: {note}", file=sys.stderr, flush=True)
    signal.signal(signal.SIGTERM, _terminate)
    line = None
    with model_board(scene=scene, aggressor_detections_per_pulse=args.aggressor_signal,
                     photon_seed=args.seed, reset_after=args.reset_after, **build) as board:
        try:
            if faults is not None:
                line = NoisyLine(board.path, to_host=faults[0], to_board=faults[1],
                                 seed=args.line_seed)
                print(line.open(), flush=True)
            else:
                print(board.path, flush=True)
            while board.failed is None:
                time.sleep(0.2)
            print(f"{parser.prog}: error: the model board stopped: {board.failed!r}",
                  file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            pass
        finally:
            if line is not None:
                line.close()
                print(f"{parser.prog}: noisy line: {describe(line)}", file=sys.stderr)
    return 0


def scene_from_args(args):
    """The :class:`~fliss.sim.scene.Scene` of the scene's and the detector's options;
    ``ValueError`` for a bad one."""
    pixels = pixels_named(args.scene, sensor=args.sensor, wall_m=args.target_m,
                          object_m=args.object_m)
    return Scene(distance_m=args.target_m, detections_per_pulse=args.signal,
                 background_hz=rate_hz(args.ambient), pixels=pixels,
                 detector=detector_from_args(args))


def _build_from_args(args):
    # The model's build and loopback from --baud, --fine-tdc, --small and --jumper
    from ...hdl.top import SMALL, FlissTop
    if args.small and args.fine_tdc:
        raise ValueError("the iCEBreaker's build has no fine TDC: --small or --fine-tdc, not both")
    top = FlissTop(**SMALL) if args.small else FlissTop(fine_tdc=args.fine_tdc)
    return {"baud": baud_rate(args.baud), "maxima": top.register_maxima(),
            "loopback": Loopback(jumper=args.jumper)}


def _terminate(number, frame):
    raise KeyboardInterrupt
