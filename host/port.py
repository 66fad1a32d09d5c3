"""Serial transport to a board: opening a port, and how long to wait for replies on it.

:func:`open_port` opens a port with :func:`serial.serial_for_url`, so a device path
(``/dev/ttyUSB1``), a pty of a virtual board (``/dev/pts/7``), ``loop://`` and
``socket://host:port`` all work the same; what users get wrong raises
:exc:`~fliss.host.errors.PortError` with one line.
"""

import errno
import os
import stat

import serial

from ..hdl.protocol import DEFAULT_BAUD
from .errors import PortError


__all__ = ["DEFAULT_TIMEOUT_S", "PTY_TIMEOUT_S", "is_pty", "default_timeout", "open_port"]


#: Seconds to wait for each reply from a board on a serial device or a URL.
DEFAULT_TIMEOUT_S = 0.5

#: Seconds to wait for each reply on a pseudo-terminal. Behind a pty there is a program, most
#: often the virtual board (a simulation, far slower than the gateware); its replies queue
#: behind the histograms it is sending, and a short timeout makes the host re-send commands the
#: board has not even read yet.
PTY_TIMEOUT_S = 5.0

# Character devices of Unix98 pty terminals on Linux (devices.txt: majors 136 to 143).
_PTY_MAJORS = range(136, 144)


def is_pty(port: str) -> bool:
    """True when ``port`` is the terminal side of a pseudo-terminal (``/dev/pts/N``, or a link to
    one such as the virtual board's ``~/.cache/fliss/virtual-board/tty``; ``/dev/ttysN`` on macOS)."""
    if "://" in port:
        return False
    path = os.path.realpath(port)
    if path.startswith("/dev/pts/") or (path.startswith("/dev/ttys") and path[9:].isdigit()):
        return True
    try:
        mode = os.stat(path)
    except OSError:
        return False
    return stat.S_ISCHR(mode.st_mode) and os.major(mode.st_rdev) in _PTY_MAJORS


def default_timeout(port: str) -> float:
    """The reply timeout for ``port`` when none is given: :data:`PTY_TIMEOUT_S` for a
    pseudo-terminal, else :data:`DEFAULT_TIMEOUT_S`."""
    return PTY_TIMEOUT_S if is_pty(port) else DEFAULT_TIMEOUT_S


def open_port(port: str, baud: int = DEFAULT_BAUD) -> serial.SerialBase:
    """``serial_for_url(port)`` with one-line errors for what users get wrong.

    A device or a pty is opened for this program alone (on POSIX, pyserial's ``exclusive``: an
    advisory ``flock`` that every fliss command takes), so that a second command on the same
    port is refused ("busy") instead of stealing replies from the first. Windows opens serial
    ports exclusively anyway; URLs (``socket://``, ``loop://``) have no such lock.
    """
    options = {"exclusive": True} if os.name == "posix" and "://" not in port else {}
    try:
        return serial.serial_for_url(port, baudrate=baud, timeout=0.05, write_timeout=2.0,
                                     **options)
    except serial.SerialException as error:
        code = getattr(error, "errno", None)
        text = str(error)
        if code == errno.ENOENT or "No such file" in text:
            raise PortError(f"no serial port {port!r} (see `fliss ports`)") from None
        if code == errno.EACCES or "Permission denied" in text:
            raise PortError(f"permission denied opening {port!r} (on Linux, add yourself to "
                            f"the dialout group and log in again)") from None
        if code in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK) or "busy" in text.lower():
            raise PortError(f"serial port {port!r} is busy (is another program using it?)") \
                from None
        raise PortError(f"cannot open serial port {port!r}: {text}") from None
    except ValueError as error:
        raise PortError(f"cannot open serial port {port!r}: {error}") from None
