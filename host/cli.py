"""The ``fliss`` command.

Each sub-command lives in its own module of :mod:`fliss.host.commands`, which provides
``register(subparsers, formatter)``: it adds its parser and sets ``run(args)`` as the parser's
``run`` default; ``args.fliss`` is :func:`main`, for a command that runs others (the demo). A command reports a user mistake by raising :class:`UserError`; it and every
:class:`~fliss.host.errors.BoardError` of the library are printed as one line.
"""

import argparse
import importlib
import logging
import re
import signal
import sys
import warnings

from .. import __version__
from .errors import BoardError, PathError, UserError, ViewError

__all__ = ["build_parser", "parse_args", "main"]


#: Modules of :mod:`fliss.host.commands`, one per sub-command, in the order of ``--help``.
COMMAND_MODULES = [
    "prf_table",
    "sequence",
    "demo",
    "reproduce",
    "sweep",
    "ports",
    "config",
    "selftest",
    "calibrate",
    "capture",
    "analyze",
    "plot",
    "export",
    "view",
    "generate",
    "board",
    "attack",
]


class _Formatter(argparse.ArgumentDefaultsHelpFormatter, argparse.RawDescriptionHelpFormatter):
    pass


#: A negative quantity, with or without its unit (``-5ms``, ``-1e6Hz``, ``-.5``): no option of
#: ``fliss`` looks like one.
_NEGATIVE = re.compile(r"-\.?\d\S*")


class _Parser(argparse.ArgumentParser):
    """An argument parser that takes a negative quantity as a value (``--integration -5ms``,
    ``--range -5ns 200ns``), so that the option's own check refuses it with its reason
    (``must be positive``); argparse takes only bare negative numbers so, and ``-5ms`` for an
    option (``expected one argument``). Its sub-command parsers are of this class too."""

    def _parse_optional(self, arg_string):
        if _NEGATIVE.fullmatch(arg_string):
            return None         # a value, not an option
        return super()._parse_optional(arg_string)


def build_parser():
    parser = _Parser(
        prog="fliss", formatter_class=_Formatter,
        description="FLISS: LiDAR interference suppression by pseudorandom pulse delays.")
    parser.add_argument("--version", action="version", version=f"fliss {__version__}")
    _add_global_options(parser, "")
    subparsers = parser.add_subparsers(metavar="COMMAND", dest="command")
    subparsers.required = True
    for name in COMMAND_MODULES:
        module = importlib.import_module(f"{__package__}.commands.{name}")
        module.register(subparsers, _Formatter)
    # The same options after the sub-command (`fliss capture -q`), counted with those before.
    for command in set(subparsers.choices.values()):
        _add_global_options(command, "command_")
    return parser


def _add_global_options(parser, prefix):
    group = parser.add_argument_group("output") if prefix else parser
    group.add_argument("-v", "--verbose", dest=prefix + "verbose", action="count", default=0,
                       help="more output (repeat for more)")
    group.add_argument("-q", "--quiet", dest=prefix + "quiet", action="count", default=0,
                       help="less output (repeat for less)")


def parse_args(argv=None):
    """The arguments of ``fliss``, with ``-v`` and ``-q`` counted before and after the
    sub-command, and ``given``: the names (``dest``) of the options given on the command line,
    so that a command can refuse one that does not apply rather than ignore it (a default,
    from the environment too, is not given)."""
    args = build_parser().parse_args(argv)
    args.verbose += getattr(args, "command_verbose", 0)
    args.quiet += getattr(args, "command_quiet", 0)
    args.given = _given(argv)
    return args


def _given(argv):
    # The same command line parsed again with no defaults: what is left was typed.
    parser = build_parser()
    parsers = [parser]
    while parsers:
        current = parsers.pop()
        current._defaults = {}      # set_defaults(run=...): not typed
        for action in current._actions:
            if isinstance(action, argparse._SubParsersAction):
                parsers.extend(set(action.choices.values()))
            elif action.dest != argparse.SUPPRESS:
                action.default = argparse.SUPPRESS
    return frozenset(vars(parser.parse_args(argv))) - {"command"}


def main(argv=None):
    try:
        args = parse_args(argv)     # (imports every command's modules: some tenths of a second)
    except KeyboardInterrupt:
        print("fliss: interrupted", file=sys.stderr)
        return 130
    from .settings import RoundingWarning

    _ignore_file_size_signal()
    level = logging.WARNING - 10 * (args.verbose - args.quiet)
    handler = logging.StreamHandler()
    handler.setFormatter(_LogFormatter())
    logging.basicConfig(level=max(logging.DEBUG, min(logging.CRITICAL, level)),
                        handlers=[handler])
    try:
        with warnings.catch_warnings():
            # A setting rounded to whole clock cycles: one line, each time.
            warnings.simplefilter("always", RoundingWarning)
            warnings.showwarning = _show_warning
            args.fliss = main
            return args.run(args) or 0
    except (UserError, BoardError, PathError, ViewError) as error:
        print(f"fliss: error: {error}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("fliss: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 0


def _ignore_file_size_signal():
    # A write past the file-size limit (ulimit -f) then fails with EFBIG, which the capture
    # reports, rather than kill fliss with SIGXFSZ. (Python ignores it when it starts; a
    # program that embeds it may not.)
    try:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    except ValueError:      # not the main thread
        pass


class _LogFormatter(logging.Formatter):
    # "fliss: warning: ..." for warnings and errors, "fliss: ..." for the rest
    def format(self, record):
        prefix = "warning: " if record.levelno >= logging.WARNING else ""
        return f"fliss: {prefix}{record.getMessage()}"


def _show_warning(message, category, filename, lineno, file=None, line=None):
    print(f"fliss: warning: {message}", file=sys.stderr)
