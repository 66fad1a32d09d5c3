"""Command-line options to reach a board (``--port``, ``--baud``, ``--timeout``, ``--retries``)
and :func:`connect`, the :class:`~fliss.host.board.Board` they describe."""

import argparse
import os

from ...hdl.protocol import DEFAULT_BAUD
from ..board import Board, connect as connect_board
from ..errors import UserError
from ..port import DEFAULT_TIMEOUT_S, PTY_TIMEOUT_S
from ..units import parse_baud, parse_time


__all__ = ["add_port_arguments", "connect"]


def add_port_arguments(parser: argparse.ArgumentParser, *, required: bool = True) -> None:
    """``--port``, ``--baud``, ``--timeout``, ``--retries``: how to reach a board. With
    ``required=False`` ``--port`` may be left out, and ``args.port`` is then None."""
    port = os.environ.get("FLISS_PORT")
    parser.add_argument("--port", required=required and port is None,
                        default=port if port is not None or not required else
                        argparse.SUPPRESS,
                        metavar="PORT",
                        help="serial port: device (/dev/ttyUSB1, COM3), pty of a virtual board "
                             "(/dev/pts/N) or pyserial URL (socket://host:port); see "
                             "`fliss ports`; the environment variable FLISS_PORT sets a "
                             "default")
    parser.add_argument("--baud", type=_baud, default=DEFAULT_BAUD,
                        help="baud rate of the port: 3M, 115200 (ignored by ptys and sockets)")
    parser.add_argument("--timeout", type=_timeout, default="auto", metavar="TIME",
                        help=f"time to wait for each reply: 5s, 500ms (a bare number: seconds); "
                             f"auto: {DEFAULT_TIMEOUT_S:g} s, or "
                             f"{PTY_TIMEOUT_S:g} s on a pty (a virtual board: a simulation, "
                             f"slow to answer while it sends histograms)")
    parser.add_argument("--retries", type=int, default=3,
                        help="times a command is re-sent when no reply comes")


def _timeout(text):
    if text == "auto":
        return None
    try:
        return float(text)
    except ValueError:
        pass
    try:
        return parse_time(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a time (5s, 500ms), a number of seconds or "
                                         f"auto: {text!r}") from None


def _baud(text):
    try:
        return parse_baud(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def connect(args: argparse.Namespace) -> Board:
    """The :class:`~fliss.host.board.Board` (:func:`fliss.host.board.connect`) of the arguments
    of :func:`add_port_arguments`, identified (so a board of another protocol version is
    refused at once)."""
    if args.timeout is not None and args.timeout <= 0:
        raise UserError(f"--timeout must be positive, not {args.timeout:g}")
    if args.baud <= 0:
        raise UserError(f"--baud must be positive, not {args.baud}")
    if args.retries < 0:
        raise UserError(f"--retries must not be negative, not {args.retries}")
    return connect_board(args.port, baud=args.baud, timeout_s=args.timeout,
                         retries=args.retries)
