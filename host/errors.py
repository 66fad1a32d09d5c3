"""Exceptions of the host library.

Everything the host library (:mod:`fliss.host.client`, :mod:`fliss.host.virtual`, ...) raises
about a board derives from :exc:`BoardError`, so a script or a notebook catches that one class.
The ``fliss`` command turns each into its one-line message (:func:`fliss.host.cli.main`), and so
it does with :exc:`UserError`, a mistake in what the user asked a command for.
"""

__all__ = ["BoardError", "BoardLost", "BoardReset", "PortError", "BoardRefused", "BoardMismatch",
           "SettingsError", "IvsUsedUp", "CalibrationError", "VirtualBoardError", "PathError", "FileFull", "FormatError", "ViewError",
           "UserError", "GatewareVersionWarning"]


class BoardError(Exception):
    """Something went wrong with a board; the message is one line that says what and what to
    do."""


class BoardLost(BoardError):
    """The board does not answer, the connection to it went away, or it stopped sending."""


class BoardReset(BoardLost):
    """The board was reset (a power cycle, a reconfiguration) while in use: its counters and
    sequence numbers started again from zero and it stopped acquiring."""


class PortError(BoardError):
    """The serial port cannot be opened (missing, busy, no permission, a bad URL)."""


class BoardRefused(BoardError):
    """The board refused a command with a NAK.

    Attributes
    ----------
    command : str
        What was refused (``"WRITE"``, ``"READ"``, ...).
    code : NakCode or int
        The NAK code (the number, for a code this host does not know).
    detail : int
        The NAK's detail: the register address refused, for example.
    register : Register or None
        The register that ``detail`` names, for a refused address or value.
    """

    def __init__(self, message, *, command=None, code=None, detail=None, register=None):
        super().__init__(message)
        self.command = command
        self.code = code
        self.detail = detail
        self.register = register


class BoardMismatch(BoardError):
    """The board is not one this host speaks to: another protocol version, another register
    map, or replies that are not FLISS packets."""


class GatewareVersionWarning(UserWarning):
    """The board speaks this host's protocol but runs gateware of another version than this
    package's (:data:`fliss.__version__`): it works, and may lack what this version's gateware
    does; program the board with this version's bitstream."""


class SettingsError(BoardError, ValueError):
    """Settings refused on the host before they were sent: an unknown register, a value out of
    its range, or settings that are not consistent."""


class IvsUsedUp(SettingsError):
    """A run in ``keyed`` mode would fire no laser pulse: the board's keyed source has used every
    IV under its key (STATUS ``ivs_used_up``) and no new key is written
    (:mod:`fliss.host.keyed`)."""


class CalibrationError(BoardError):
    """The fine TDC cannot be calibrated: the board has none, its oscillator gave no hits, or
    the board did not keep the table written (:mod:`fliss.host.calibration`)."""


class VirtualBoardError(BoardError):
    """The virtual board (a simulation of the gateware) cannot be built or started, or it
    stopped."""


class PathError(ValueError):
    """A file or folder named by the user cannot be written (or read) as asked: a missing or
    read-only folder, a folder where a file is wanted, a device, a file that exists; the
    message is one line that says what and what to do. Raised before anything is started, by
    :mod:`fliss.host.paths`, or when a file stops taking data (a full disk) during a capture,
    after the board is stopped and the file closed."""


class FileFull(OSError):
    """A capture file cannot grow by what comes next: the disk is full, or the process's
    file-size limit (``ulimit -f``) would be passed. Raised by the writer before it writes, so
    that the file stays whole (HDF5 that fails mid-write leaves a file no one can open);
    ``errno`` is ``ENOSPC`` or ``EFBIG`` and ``strerror`` says which, with the bytes left."""


class FormatError(ValueError):
    """A capture cannot be exported to the format asked for (a depth capture to PTU, a
    histogram to Photon-HDF5, a library missing), or a PTU or Photon-HDF5 file cannot be read
    as a capture; the message is one line that says why (:mod:`fliss.host.formats`)."""


class ViewError(Exception):
    """The live view cannot be served: its port is in use or cannot be bound, or the web
    server does not start; the message is one line that says why (:mod:`fliss.host.view`)."""


class UserError(Exception):
    """A mistake in what the user asked for, or an environment failure; one line, no traceback."""
