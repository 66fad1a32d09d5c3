"""``fliss capture``: histograms, per-pixel histograms (images), depth frames or raw events
from a board into an HDF5 file.

The capture itself is :meth:`fliss.host.board.Board.capture` (at the board's settings, after
those of the flags given); this module adds the command line, the progress bar and the report.
"""

import argparse
import signal
import sys

from ..acquisition import left_running
from ...hdl.registers import BY_NAME, AcquisitionMode
from ..errors import BoardReset, FormatError, UserError
from ..formats import check_name
from ..imager.threshold import nothing_detected
from ..keyed import used_up_by
from ..kinds import KINDS, kind_of, mode_of
from ..paths import check_output_path
from ..pointcloud.options import add_geometry_options, geometry_of, recorded_geometry
from .common import Progress
from .port_options import add_port_arguments, connect
from .setting_options import add_setting_arguments, settings_from_args
from .view_options import (add_view_arguments, check_bokeh, check_view_flags,
                           setup_options, viewing)
from ..settings import Settings, check_offline, convert, duration_s


__all__ = ["register", "run", "report"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "capture", formatter_class=formatter,
        help="capture histograms, images, depth frames or raw events into an HDF5 file",
        description="Captures at the board's settings (as `fliss config` left them), changed "
                    "first by any setting flags given here: starts the board and writes what "
                    "it sends to FILE as it arrives (schema: docs/file-format.md), with the "
                    "board's registers as used, its identity and the link's counters. "
                    "Ctrl-C, kill (SIGTERM) or a closed terminal (SIGHUP) stops the acquisition "
                    "on the board and keeps what was captured; a board that stops answering, "
                    "or is reset, leaves a file with everything received; after kill -9 the "
                    "file holds all but the last half second (docs/file-format.md). "
                    "--readout image saves per-pixel histograms (frame, pixel, bin) and "
                    "--readout depth the board's depth frames (frame, pixel); the readout "
                    "is --readout, as --mode is the victim's delay source.")
    add_port_arguments(parser)
    parser.add_argument("--acquisitions", type=int, default=10, metavar="N",
                        help="frames to capture (histogram, image and depth readouts only: "
                             "refused with the raw readout)")
    parser.add_argument("--duration", default="1s", metavar="TIME",
                        help="how long to capture, on the host's clock (raw readout only: "
                             "refused with the others)")
    parser.add_argument("--output", "-o", required=True, metavar="FILE.h5",
                        default=argparse.SUPPRESS,
                        help="HDF5 file to write")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing FILE")
    parser.add_argument("--any-extension", action="store_true",
                        help="write FILE under a name not ending in .h5 or .hdf5, which is "
                             "refused otherwise (a capture is an HDF5 file)")
    parser.add_argument("--view", action="store_true",
                        help="show the capture live in the browser meanwhile (as `fliss view`; "
                             "the view samples what is written and never holds it up)")
    add_view_arguments(parser, "the live view (with --view)")
    add_geometry_options(parser)
    add_setting_arguments(parser, "settings (as in `fliss config`; those not given keep the "
                                  "board's values: --readout histogram|image|depth|raw, "
                                  "--pixels N, --integration TIME, --mode for the delay "
                                  "source, ...)")
    parser.set_defaults(run=run)


def run(args):
    settings = settings_from_args(args)
    check_offline(settings)         # before the board: wrong on any board
    duration_s(args.duration, f"--duration {args.duration}")
    if args.acquisitions < 1:
        raise UserError(f"--acquisitions must be at least 1, not {args.acquisitions}")
    check_output_path(args.output, overwrite=args.overwrite)      # before the board
    if not getattr(args, "any_extension", False):
        try:
            check_name(args.output, "fliss", flag="-o")
        except FormatError as error:
            raise UserError(str(error)) from None
    given = getattr(args, "given", frozenset())
    geometry = recorded_geometry(args)      # (recorded for the depth frames' points)
    if args.view:
        check_bokeh()
    else:
        check_view_flags(given)
    quiet = getattr(args, "quiet", 0) > 0
    with connect(args) as board:
        warning = left_running(board.client, "this capture stops it and starts it again")
        if warning:
            print(f"fliss: warning: {warning}", file=sys.stderr)
        # before the settings change: a refusal leaves the board as it was
        check_applies(given, settings.get("readout"), board.settings["readout"])
        if args.view:       # the view's options against the frame the settings will make
            registers = convert(settings, board.clock_hz, board.client.read_registers(),
                                style="flag", bank_bits=board.bank_bits).registers
            setup_options(args, Settings(registers, board.clock_hz).addresses)
        board.configure(settings, style="flag")
        readout = board.settings["readout"]
        # (a kind that is the per-pixel form of another is asked for by its name)
        image = True if settings.get("readout") in _PER_PIXEL else None
        kind = kind_of(mode_of(readout, int(board.settings["pixels"] > 1), image))
        if kind.framed:
            bar = Progress(args.acquisitions, kind.rows, enabled=not quiet)
        else:
            bar = Progress(round(duration_s(args.duration, ""), 1), "s", enabled=not quiet)
        with viewing(board, args, geometry_of(args)[0]) as feed:
            result = board.capture(args.output, acquisitions=args.acquisitions,
                                   duration=args.duration, progress=bar, image=image,
                                   overwrite=args.overwrite, watch=feed, geometry=geometry)
    try:
        return report(result, quiet=quiet)
    except OSError:     # the terminal went away (SIGHUP); the file is saved all the same
        return 128 + result.signal if result.signal else 1


#: The readouts that capture frames (--acquisitions of them), and those that capture for
#: --duration (raw).
_FRAMED = [name for name, kind in KINDS.items() if kind.framed]
_TIMED = [name for name, kind in KINDS.items() if not kind.framed]

#: The board's readout at reset.
_RESET = AcquisitionMode(BY_NAME["acquisition"].reset).name.lower()

#: The readouts that are the per-pixel form of another (image).
_PER_PIXEL = {kind.per_pixel for kind in KINDS.values() if kind.per_pixel}


def check_applies(given, requested, board_readout):
    """Refuse ``--acquisitions`` with the raw readout and ``--duration`` with the others
    (``given``: the options typed, as ``args.given``), rather than ignore them: the readout is
    ``requested`` (``--readout``, None when not given) or else ``board_readout``, the board's."""
    readout = requested or board_readout
    if requested:
        source = f"--readout {requested} is given here"
    else:
        source = (f"the board's readout is {board_readout} (" + (
            "its reset value, or as an earlier command left it)" if board_readout == _RESET
            else "set by an earlier `fliss config` or capture)"))
    if readout in _TIMED and "acquisitions" in given:
        framed = f"{', '.join(_FRAMED[:-1])} and {_FRAMED[-1]}"
        raise UserError(f"--acquisitions applies to the {framed} readouts, not {readout}, and "
                        f"{source}: give --readout {_FRAMED[0]} (or {', '.join(_FRAMED[1:])}), "
                        f"or --duration TIME for {KINDS[readout].what}")
    if readout in _FRAMED and "duration" in given:
        raise UserError(f"--duration applies to the {' and '.join(_TIMED)} readout only, and "
                        f"{source}: give --acquisitions N for {readout} frames, or --readout "
                        f"{_TIMED[0]}")


def report(result, *, quiet=False, out=None):
    """Print what :func:`~fliss.host.acquisition.capture` saved and warn about what was lost;
    returns the exit status (128 + the signal when interrupted: 130 for Ctrl-C, 143 for
    SIGTERM, 129 for SIGHUP). Raises :exc:`UserError` when the board
    was lost."""
    out = sys.stdout if out is None else out
    link, stream, what, path = result.link, result.stream, result.what, result.path
    status_start, status_end = result.status_start, result.status_end
    damaged = link["dropped_frames"] + link["missing_packets"]
    board_dropped = result.board_dropped
    if not quiet:
        print(f"saved {what} to {path}", file=out)
        print(f"link: {link['bytes']} bytes, {link['packets']} packets, "
              f"{link['dropped_frames']} corrupt frames dropped, "
              f"{link['missing_packets']} packets missing, "
              f"{stream['incomplete_rows']} incomplete histograms, "
              f"{stream['lost_rows']} histograms lost", file=out)
        if status_end is not None:
            print(f"board: {status_end['events'] - status_start['events']} events accepted, "
                  f"{board_dropped} dropped on the board, "
                  f"{status_end['frames'] - status_start['frames']} "
                  f"{'histograms' if KINDS[result.mode].counted else 'frames'}", file=out)
        deliberate = result.board_deliberate
        if any(deliberate.values()):
            print(f"board: {deliberate.get('dropped_collision', 0)} events flagged as "
                  f"collisions dropped (--collisions drop), {deliberate.get('dropped_pixel', 0)}"
                  f" events of pixels outside the frame dropped (counted in the file)", file=out)
    if damaged and not isinstance(result.lost, BoardReset):
        print(f"fliss: warning: {link['dropped_frames']} corrupt frames and "
              f"{link['missing_packets']} missing packets on the link (counted in the file)",
              file=sys.stderr)
    queue_frames = stream.get("queue_dropped_frames", 0)
    queue_events = stream.get("queue_dropped_events", 0)
    if queue_frames or queue_events:
        print(f"fliss: warning: {queue_frames} frames and {queue_events} events dropped on the "
              f"host, whose queue of data not yet written was full (counted in the file; the "
              f"frames' rows are marked lost)", file=sys.stderr)
    if board_dropped:
        advice = ("the link is too slow for this event rate; use a higher baud rate or "
                  "histogram mode") if not KINDS[result.mode].framed else \
            ("events arrived while no histogram was filling, as the previous one was still "
             "being sent; use a longer integration time, a larger bin shift or a higher baud "
             "rate")
        print(f"fliss: warning: {board_dropped} events dropped on the board (counted in the "
              f"file): {advice}", file=sys.stderr)
    # (a threshold is known of captures of depth frames only)
    if result.threshold is not None and not result.detections:
        arrived = result.histograms - result.lost_histograms
        print(f"fliss: warning: "
              f"{nothing_detected(arrived, result.highest, result.threshold)}", file=sys.stderr)
    spent = used_up_by(status_start, status_end)
    if spent:
        print(f"fliss: warning: {spent}", file=sys.stderr)
    if result.lost is not None:
        raise UserError(f"{result.lost}; saved what was received ({what}) to {path}")
    if result.interrupted:
        # The shell's status of a process killed by the signal: 130 Ctrl-C, 143 kill, 129 hangup.
        signum = result.signal or signal.SIGINT
        name = "" if signum == signal.SIGINT else f" by {signum.name}"
        print(f"fliss: interrupted{name}; acquisition stopped, capture saved", file=sys.stderr)
        return 128 + signum
    return 0
