"""``fliss view``: a live view of a board in the browser, or the replay of a capture file.

The view itself is :mod:`fliss.host.view` (a Bokeh server on a thread, fed by the acquisition);
this module adds the command line. ``fliss capture --view`` serves the same page while it
captures.
"""

import math
import os
import sys
import time

from ..board import Board
from ..errors import UserError
from ..settings import Settings, check_offline, duration_s
from .common import read_capture_file, sigterm_interrupts
from .port_options import add_port_arguments, connect
from .setting_options import add_setting_arguments, settings_from_args
from .view_options import add_view_arguments, check_bokeh, serving, setup_options
from ..pointcloud.options import geometry_of


__all__ = ["register", "run"]


#: The options of a board's link (:func:`~.port_options.add_port_arguments`), refused with FILE.
_LINK_FLAGS = ("--port", "--baud", "--timeout", "--retries")


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "view", formatter_class=formatter,
        help="watch a board (or replay a capture) in the browser, live",
        description="Serves a page on this machine (the address is printed) that shows what "
                    "the board sends, frame by frame, in any number of browsers: the "
                    "histogram (linear and log), the peak table (ToF, distance, FWHM, "
                    "height) and the suppression S, frames, count and drop rates; for the "
                    "imager, the depth profile (an image with --shape) and the intensity. "
                    "With --port, the board acquires at its settings (as `fliss config` left "
                    "them, changed first by any setting flag given) until Ctrl-C, and is "
                    "stopped then; with FILE, a capture (FLISS, PTU or Photon-HDF5) is played "
                    "back at the pace it was captured (--speed). `fliss capture --view` "
                    "shows a capture as it is written.")
    parser.add_argument("file", nargs="?", metavar="FILE",
                        help="capture file (or a PTU, Photon-HDF5, HT3, PT3 or SPC file) to "
                             "replay (instead of --port)")
    add_port_arguments(parser, required=False)
    parser.add_argument("--speed", type=float, default=1.0, metavar="X",
                        help="replay this many times faster than the capture ran")
    parser.add_argument("--loop", action="store_true", help="replay the file again and again")
    parser.add_argument("--for", dest="duration", metavar="TIME",
                        help="stop after this long (none: at Ctrl-C)")
    add_view_arguments(parser, "the page")
    add_setting_arguments(parser, "settings of the board (as in `fliss config`; those not "
                                  "given keep the board's values)")
    parser.set_defaults(run=run)


def run(args):
    check_bokeh()
    from ..view.feed import READOUTS, Feed, Setup

    settings = settings_from_args(args)
    limit_s = duration_s(args.duration, f"--for {args.duration}") if args.duration else None
    given = getattr(args, "given", frozenset())
    if args.file is not None:
        if settings:
            flags = ", ".join("--" + name.replace("_", "-") for name in settings)
            raise UserError(f"{flags}: settings are for a board, not for a file to replay")
        link = [flag for flag in _LINK_FLAGS if flag[2:] in given]
        if link:
            raise UserError(f"{', '.join(link)}: {'options' if len(link) > 1 else 'an option'}"
                            f" of a board's link, and FILE ({args.file}) is replayed from the "
                            f"file: give FILE or --port, not both")
        if not 0 < args.speed < math.inf:
            raise UserError(f"--speed must be positive and finite, not {args.speed:g}")
        capture = read_capture_file(args.file)
        recorded = capture.attrs.get("geometry")
        geometry = None if recorded is None else geometry_of(args, str(recorded), args.file)[0]
        setup = Setup.of_capture(capture, **setup_options(args, capture.pixels, geometry))
        return _replay(capture, Feed(setup), args, limit_s)
    if args.port is None:
        raise UserError("give a capture FILE to replay, or --port (or FLISS_PORT) to watch a "
                        "board")
    replay = [flag for flag in ("--speed", "--loop") if flag[2:] in given]
    if replay:
        raise UserError(f"{', '.join(replay)}: {'options' if len(replay) > 1 else 'an option'}"
                        f" of the replay of a FILE, not of a board watched live")
    check_offline(settings)
    with connect(args) as board:
        board.configure(settings, style="flag")
        registers = board.client.read_registers()
        addresses = Settings(registers, board.clock_hz).addresses
        setup = Setup.of_registers(board.port, registers, board.clock_hz,
                                   **setup_options(args, addresses))
        if setup.readout not in READOUTS:
            raise UserError(f"fliss view shows {', '.join(READOUTS)} readouts, not "
                            f"{setup.readout}")
        return _watch(board, Feed(setup), args, limit_s)


def _watch(board: Board, feed, args, limit_s):
    from ..view.live import watch

    end = None if limit_s is None else time.monotonic() + limit_s
    with serving(feed, args):
        try:
            with sigterm_interrupts():
                watch(board, feed, should_stop=lambda: end is not None and
                      time.monotonic() >= end)
        except KeyboardInterrupt:
            print("fliss: view stopped; the board stopped acquiring", file=sys.stderr)
    return 0


def _replay(capture, feed, args, limit_s):
    from ..view.replay import MAX_RATE_HZ, Replay

    end = None if limit_s is None else time.monotonic() + limit_s
    watched = _FileWatch(capture.path)     # (its size as read: before the page is served)
    with serving(feed, args):
        replay = Replay(capture, feed, speed=args.speed, loop=args.loop)
        if replay.slowed > 1:
            print(f"fliss: view: {len(replay.items)} frames played {replay.slowed:.3g} times "
                  f"slower than --speed {args.speed:g} asks: a replay hands the view at most "
                  f"{MAX_RATE_HZ:g} a second", file=sys.stderr, flush=True)
        replay.start()
        said = False
        try:
            with sigterm_interrupts():
                while end is None or time.monotonic() < end:
                    watched.check()
                    if not said and replay.wait(0.1):
                        said = True
                        stays = ("until Ctrl-C" if end is None else
                                 f"until Ctrl-C or the end of --for {args.duration}")
                        print(f"fliss: view: {feed.state}; the page stays {stays}",
                              file=sys.stderr, flush=True)
                    elif said:
                        time.sleep(0.1)
        except KeyboardInterrupt:
            print("fliss: view stopped", file=sys.stderr)
        finally:
            replay.stop()
    return 0


class _FileWatch:
    """The replayed file, read whole when the view started: removed or cut short since, it
    says so in one warning line, once, and the view goes on with what it read."""

    def __init__(self, path):
        self.path = path
        self.size = self._size()
        self.said = False

    def _size(self):
        try:
            return os.path.getsize(self.path)
        except OSError:
            return None

    def check(self):
        if self.said or self.size is None:
            return
        now = self._size()
        if now is not None and now >= self.size:
            return
        self.said = True
        what = "was removed" if now is None else \
            f"was cut short (from {self.size} to {now} bytes)"
        print(f"fliss: warning: {self.path} {what} while shown; the view goes on with the "
              f"capture as it was read when it started", file=sys.stderr, flush=True)
