"""Checks of the files and folders a command will write, made before it starts any work.

Every command that writes (``fliss capture -o``, ``fliss plot -o``, ``fliss generate -o``,
``fliss reproduce --out``, ...) checks its output here first, so that a path it cannot write is
refused with one line (:exc:`~fliss.host.errors.PathError`) before a board is touched or a
simulation runs, and never ends in a traceback after the work is done.
"""

import errno
import os
import tempfile
from pathlib import Path
from typing import Optional

from .errors import PathError


__all__ = ["check_output_path", "check_output_dir"]


def _text(path, flag):
    text = os.fspath(path)
    if not text:
        raise PathError(f"{flag}: an empty name is no file name")
    if "\0" in text:
        raise PathError(f"{flag}: {text!r} holds a NUL character")
    return text


def _reason(error):
    if error.errno == errno.EROFS:
        return "the file system is read-only"
    return (error.strerror or str(error)).lower()


def check_output_path(path, *, overwrite: Optional[bool] = False, flag: str = "--output",
                      overwrite_flag: str = "--overwrite") -> Path:
    """Check that a file can be written at ``path``, before any work; returns it as a Path.

    Refused with :exc:`~fliss.host.errors.PathError`: a folder (even to overwrite), something
    that is not a regular file (a device, a pipe), a folder that does not exist or cannot be
    written in (permissions, a read-only file system), and an existing file unless
    ``overwrite`` is true (``overwrite=None``: a command that always replaces its output).
    Nothing is left behind: a probe file made to test the folder is removed at once.
    """
    text = _text(path, flag)
    target = Path(text)
    if target.is_dir():
        raise PathError(f"{flag}: {text} is a folder; give the name of a file to write")
    folder = target.absolute().parent
    if not folder.exists():
        raise PathError(f"cannot write {text}: no folder {folder} (make it first)")
    if not folder.is_dir():
        raise PathError(f"cannot write {text}: {folder} is not a folder")
    if target.exists() or target.is_symlink():
        if not target.is_file():
            raise PathError(f"cannot write {text}: it is not a regular file (a device or a "
                            f"pipe?); give the name of a file to write")
        if overwrite is False:
            raise PathError(f"{text} exists (use {overwrite_flag} to replace it)")
        try:
            os.close(os.open(text, os.O_WRONLY))
        except OSError as error:
            raise PathError(f"cannot write {text}: {_reason(error)}") from None
        return target
    try:
        os.close(os.open(text, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644))
    except OSError as error:
        raise PathError(f"cannot write {text}: {_reason(error)} (in {folder})") from None
    os.unlink(text)
    return target


def check_output_dir(path, *, flag: str = "--output") -> Path:
    """Make the folder ``path`` (and its parents) if missing and check that files can be
    written in it, before any work; returns it as a Path. Refused with
    :exc:`~fliss.host.errors.PathError`: a file of that name, a folder that cannot be made or
    written in."""
    text = _text(path, flag)
    folder = Path(text)
    if folder.exists() and not folder.is_dir():
        raise PathError(f"{flag}: {text} is a file, not a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise PathError(f"cannot make the folder {text}: {_reason(error)}") from None
    try:
        handle, probe = tempfile.mkstemp(prefix=".fliss-probe-", dir=folder)
    except OSError as error:
        raise PathError(f"cannot write in the folder {text}: {_reason(error)}") from None
    os.close(handle)
    os.unlink(probe)
    return folder
