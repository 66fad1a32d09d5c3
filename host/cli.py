"""The ``fliss`` command.

Each sub-command lives in its own module of :mod:`fliss.host`, which provides
``register(subparsers)``: it adds its parser and sets ``run(args)`` as the parser's ``run``
default. A command reports a user mistake by raising :class:`UserError`; it and every
:class:`~fliss.host.errors.BoardError` of the library are printed as one line.
"""

import argparse
import importlib
import logging
import sys

from .. import __version__
from .errors import BoardError, PathError


__all__ = ["UserError", "main"]


#: Modules of :mod:`fliss.host` that provide sub-commands, in the order of ``--help``.
COMMAND_MODULES = [
    "model_commands",
    "demo",
    "reproduce",
    "ports",
    "config",
    "capture",
    "plot_commands",
    "generate",
    "board_command",
]


class UserError(Exception):
    """A mistake in what the user asked for, or an environment failure; one line, no traceback."""


class _Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    pass


def build_parser():
    parser = argparse.ArgumentParser(
        prog="fliss", formatter_class=_Formatter,
        description="FLISS: LiDAR interference suppression by pseudorandom pulse delays.")
    parser.add_argument("--version", action="version", version=f"fliss {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0,
                        help="more output (repeat for more)")
    parser.add_argument("-q", "--quiet", action="count", default=0,
                        help="less output (repeat for less)")
    subparsers = parser.add_subparsers(metavar="COMMAND", dest="command")
    subparsers.required = True
    for name in COMMAND_MODULES:
        module = importlib.import_module(f"{__package__}.{name}")
        module.register(subparsers, _Formatter)
    return parser


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    level = logging.WARNING - 10 * (args.verbose - args.quiet)
    logging.basicConfig(level=max(logging.DEBUG, min(logging.CRITICAL, level)),
                        format="fliss: %(message)s")
    try:
        return args.run(args) or 0
    except (UserError, BoardError, PathError) as error:
        print(f"fliss: error: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("fliss: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0
