"""The setting flags of ``fliss config`` and ``fliss capture``, one per entry of
:data:`fliss.host.settings.OPTIONS` (``--mask-width`` for ``mask_width``), and
:func:`settings_from_args`, the settings they give, for :meth:`fliss.host.board.Board.configure`."""

import argparse
from typing import Dict

from ..settings import OPTIONS


__all__ = ["add_setting_arguments", "settings_from_args"]


def add_setting_arguments(parser: argparse.ArgumentParser, title: str) -> None:
    """A flag for each setting, in a group called ``title``; a flag not given leaves its
    setting as the board has it."""
    group = parser.add_argument_group(title)
    for option in OPTIONS:
        names = [option.flag]
        if option.name == "scheduler":
            # --grid and --interval: short for --scheduler grid / interval
            group.add_argument("--grid", "--interval", dest="scheduler", action=_Scheduler,
                               nargs=0, default=argparse.SUPPRESS,
                               help="short for --scheduler grid, --scheduler interval")
        group.add_argument(*names, dest=option.name, default=argparse.SUPPRESS,
                           choices=list(option.choices) if option.choices else None,
                           metavar=option.metavar, help=option.help)


class _Scheduler(argparse.Action):
    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, option_string.lstrip("-"))


def settings_from_args(args: argparse.Namespace) -> Dict[str, str]:
    """The settings given on the command line, by name, as typed."""
    return {option.name: getattr(args, option.name) for option in OPTIONS
            if hasattr(args, option.name)}
