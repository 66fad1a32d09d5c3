"""Where the virtual board's builds and the links to its ptys live: a per-user cache.

The cache is ``$FLISS_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/fliss``, else
``~/.cache/fliss`` (:func:`cache_root`), the same from a checkout and from an installed wheel
(whose site-packages may be read-only), whatever the working folder. Its ``virtual-board/``
(:func:`build_root`) holds:

* one folder per build, named by what it runs and a key (:func:`build_folder`):
  ``fast-<key>`` (the C++ harness: :func:`fliss.sim.boards.harness.key`), ``<sim>-<key>``,
  ``<sim>-fine-<key>``, ``<sim>-small-<key>`` (cocotb); the key is a digest of the gateware's
  sources, the Amaranth version, the baud rate and the build's options, so two checkouts, two
  baud rates or two builds never share a folder, and a folder of another key is another
  gateware's (or stale). Each holds ``last-used``, touched at each start; a folder unused for
  :data:`STALE_DAYS` days is removed at the next start of any board (:func:`prune`);
* ``tty``, ``tty-2``, ...: a link to each running board's pty (:func:`claim_link`); a link
  whose pty is gone (its board was killed) is removed at the next start
  (:func:`remove_stale_links`).
"""

import contextlib
import fcntl
import itertools
import os
import shutil
import time
from pathlib import Path


__all__ = ["CACHE_ENV", "STALE_DAYS", "cache_root", "build_root", "build_folder", "touch",
           "prune", "claim_link", "release_link", "remove_stale_links"]


#: The environment variable that moves the cache.
CACHE_ENV = "FLISS_CACHE_DIR"
#: Days a build may go unused before the next start removes it.
STALE_DAYS = 30


def cache_root() -> Path:
    """``$FLISS_CACHE_DIR``, else ``$XDG_CACHE_HOME/fliss``, else ``~/.cache/fliss``."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    return Path(os.environ.get("XDG_CACHE_HOME") or "~/.cache").expanduser() / "fliss"


def build_root() -> Path:
    """The virtual board's builds and pty links: ``virtual-board/`` of :func:`cache_root`."""
    return cache_root() / "virtual-board"


def build_folder(root, kind: str, key: str) -> Path:
    """The folder of a build of ``kind`` (``fast``, ``verilator-fine``, ...) with ``key``."""
    return Path(root) / f"{kind}-{key[:16]}"


def touch(folder) -> None:
    """Mark ``folder``'s build as used now."""
    Path(folder, "last-used").touch()


def prune(root, *, keep=(), days: float = STALE_DAYS) -> list:
    """Remove the build folders in ``root`` unused for ``days`` (by their ``last-used``, else
    their own time), but those in ``keep`` and those being built (their lock held); returns
    the folders removed."""
    removed = []
    limit = time.time() - days * 86400
    keep = {Path(folder).resolve() for folder in keep}
    for folder in Path(root).glob("*-*"):
        if not folder.is_dir() or folder.is_symlink() or folder.resolve() in keep:
            continue
        used = folder / "last-used"
        with contextlib.suppress(OSError):
            if (used if used.exists() else folder).stat().st_mtime > limit:
                continue
            with open(folder / "build.lock", "a") as lock:
                try:
                    fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    continue            # being built or used
                shutil.rmtree(folder, ignore_errors=True)
                removed.append(folder)
    return removed


def claim_link(root, path):
    """Link ``path`` (a board's pty) as ``root/tty``, or as ``tty-2``, ``tty-3``, ... when a
    running board holds that name (a link to a pty that is gone is taken over); returns the
    link, or None if none can be made."""
    for number in itertools.count(1):
        link = Path(root) / ("tty" if number == 1 else f"tty-{number}")
        try:
            link.symlink_to(path)           # (atomic: two boards never take one name)
            return link
        except FileExistsError:
            if link.is_symlink() and not link.exists():     # a board that is gone
                with contextlib.suppress(FileNotFoundError):
                    link.unlink()
                try:
                    link.symlink_to(path)
                    return link
                except FileExistsError:     # another board took it meanwhile
                    continue
        except OSError:
            return None


def release_link(link, path):
    """Remove ``link`` if it still points to ``path``."""
    with contextlib.suppress(OSError):
        if os.readlink(link) == path:
            link.unlink()


def remove_stale_links(root) -> list:
    """Remove the ``tty`` links in ``root`` whose pty is gone (boards killed without a chance
    to remove their own); returns their names."""
    removed = []
    for link in sorted(Path(root).glob("tty*")):
        if link.is_symlink() and not link.exists():
            with contextlib.suppress(FileNotFoundError):
                link.unlink()
                removed.append(link.name)
    return removed
