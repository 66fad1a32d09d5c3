"""The live view's options (``--view-port``, ``--view-address``, ``--victim-tof``, ``--shape``)
for ``fliss view`` and ``fliss capture --view``, and :func:`serving`, the view they describe
served for the length of a ``with`` block."""

import argparse
import contextlib
import sys

from ..errors import UserError
from .common import parse_times


__all__ = ["VIEW_FLAGS", "add_view_arguments", "setup_options", "check_bokeh",
           "check_view_flags", "serving", "viewing"]


#: The view's options, by ``dest``, as typed.
VIEW_FLAGS = {"view_port": "--view-port", "view_address": "--view-address",
              "victim_tof": "--victim-tof", "shape": "--shape"}


def add_view_arguments(parser: argparse.ArgumentParser, title: str) -> None:
    """The view's options, in a group called ``title``."""
    from ..view.server import DEFAULT_PORT

    group = parser.add_argument_group(title)
    group.add_argument("--view-port", type=int, default=DEFAULT_PORT, metavar="N",
                       help="TCP port of the view's page (0: any free port; the address is "
                            "printed)")
    group.add_argument("--view-address", default="localhost", metavar="HOST",
                       help="address the page is served on, and opened at: localhost for this "
                            "machine only; this machine's name to serve the network "
                            "(http://NAME:PORT/)")
    group.add_argument("--victim-tof", metavar="TIME",
                       help="position of the victim's peak for S (e.g. 26.7ns); else the "
                            "roles come from the board's settings, as in fliss analyze (with "
                            "FLISS off: unknown, and no S)")
    group.add_argument("--shape", metavar="ROWSxCOLUMNS",
                       help="the imager's pixels as an image (8x8) rather than a profile (by "
                            "default: an image when the sensor's geometry is a grid the "
                            "frame's pixels fill, a profile otherwise)")


def setup_options(args, addresses, geometry=None) -> dict:
    """``victim_s`` and ``shape`` for :class:`~fliss.host.view.feed.Setup`, from the
    arguments: ``addresses`` are the frame's pixel addresses (``--shape`` must hold as many);
    without ``--shape``, the image shape the sensor's ``geometry`` (a
    :class:`~fliss.host.pointcloud.geometry.SensorGeometry`, or None) gives them, if any."""
    from ..imager.report import parse_shape

    victim = parse_times([args.victim_tof], "--victim-tof")[0] if args.victim_tof else None
    if args.shape is not None or geometry is None:
        shape = parse_shape(args.shape, max(len(addresses), 1))
    else:
        shape = geometry.image_shape(addresses)
    return {"victim_s": victim, "shape": shape}


def check_view_flags(given) -> None:
    """For ``fliss capture`` without ``--view``: refuse the view's options among ``given``
    (the options typed), which nothing would use."""
    typed = [flag for dest, flag in VIEW_FLAGS.items() if dest in given]
    if typed:
        raise UserError(f"{', '.join(typed)}: {'options' if len(typed) > 1 else 'an option'} "
                        f"of the live view, which this capture does not show: add --view")


def check_bokeh() -> None:
    """Refuse with one line when Bokeh, which serves the view, is not installed."""
    try:
        import bokeh  # noqa: F401
    except ImportError:
        raise UserError("the live view needs Bokeh: pip install 'fliss[view]'") from None


@contextlib.contextmanager
def serving(feed, args, *, quiet=False):
    """Serve the view of ``feed`` as the arguments say, for the length of the ``with`` block
    (yields the :class:`~fliss.host.view.server.ViewServer`); prints its address, and a line
    when a browser opens or leaves the page (stderr)."""
    from ..view.server import ViewServer

    def notify(line):
        if not quiet:
            _say(f"fliss: view: {line}")

    with ViewServer(feed, port=args.view_port, address=args.view_address,
                    notify=notify) as server:
        _say(f"fliss: view at {server.url} (Ctrl-C stops)")
        yield server


@contextlib.contextmanager
def viewing(board, args, geometry=None):
    """For ``fliss capture``: with ``--view``, the view of ``board`` at its settings served for
    the length of the ``with`` block, which gets its :class:`~fliss.host.view.feed.Feed` to
    hand the capture; None without. ``geometry``: the sensor's, which may make the depth an
    image (:func:`setup_options`)."""
    if not args.view:
        yield None
        return
    from ..settings import Settings
    from ..view.feed import Feed, Setup

    registers = board.client.read_registers()
    addresses = Settings(registers, board.clock_hz).addresses
    feed = Feed(Setup.of_registers(board.port, registers, board.clock_hz,
                                   **setup_options(args, addresses, geometry)))
    with serving(feed, args, quiet=getattr(args, "quiet", 0) > 0):
        yield feed


def _say(line):
    try:
        print(line, file=sys.stderr, flush=True)
    except OSError:         # the terminal went away: the view and the capture go on
        pass
