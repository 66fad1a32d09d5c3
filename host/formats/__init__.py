"""Captures in other programs' formats, both ways: PTU (PicoQuant) and Photon-HDF5; and the
recordings of other TCSPC instruments (HT3, PT3, Becker & Hickl SPC) read.

:func:`export_capture` writes a capture (:class:`~fliss.host.fileformat.Capture`) in one of
:data:`FORMATS`; :func:`read_file` reads a FLISS capture file, a PTU file, an HT3, PT3 or SPC
file (:mod:`.tttr_foreign`) or a Photon-HDF5 file as a capture, so that ``fliss analyze``,
``fliss plot``, ``fliss view`` and ``fliss export`` take any of them. What maps to
what, and what is lost: docs/file-format.md. Everything refused is a :exc:`FormatError` (a
``ValueError``) of one line.

Which kinds of data an export format takes is the kind's (:attr:`fliss.host.kinds.DataKind.
exports`, and its :attr:`~fliss.host.kinds.DataKind.refusal` when none does): a new export
format is a row of :data:`FORMATS` and its name in the kinds that it takes. A new reader of
another program's files is a module here and a test of its files' mark in :func:`read_file`;
it returns a capture of one of the kinds (``mode``), as :mod:`.metadata` makes them.
"""

import os

from ..errors import FormatError
from ..fileformat import read_capture
from ..kinds import KINDS, article
from .photon_hdf5 import is_photon_hdf5, read_photon_hdf5, write_photon_hdf5
from .ptu import read_ptu, write_ptu
from .ptu_header import read_header
from .tttr_foreign import foreign_kind, read_foreign


__all__ = ["FORMATS", "ENDINGS", "FormatError", "check_name", "export_capture", "export_refusal",
           "read_file"]


#: Export formats by name: (description, writer). Which kinds of data each takes is the kind's
#: (:attr:`fliss.host.kinds.DataKind.exports`): a new format is a row here and its name in the
#: kinds it takes.
FORMATS = {
    "ptu": ("PTU (PicoQuant)", write_ptu),
    "photon-hdf5": ("Photon-HDF5", write_photon_hdf5),
}

#: What a file of each format (and a FLISS capture, ``"fliss"``) is called, and the endings of
#: its name, the first the one to give: other programs go by them.
ENDINGS = {
    "ptu": ("a PTU file", (".ptu",)),
    "photon-hdf5": ("a Photon-HDF5 file", (".hdf5", ".h5")),
    "fliss": ("a FLISS capture (HDF5)", (".h5", ".hdf5")),
    "ply": ("a PLY file", (".ply",)),
    "pcd": ("a PCD file", (".pcd",)),
    "las": ("a LAS file", (".las",)),
    "mcap": ("an MCAP file", (".mcap",)),
    "mcap-ros2": ("an MCAP file", (".mcap",)),
}

_PTU = b"PQTTTR\0\0"
_PHU = b"PQHISTO\0"


def check_name(path, to, *, flag="--output", allow="--any-extension"):
    """Refuse (:exc:`FormatError`) a file name ``path`` whose ending is not one of the format
    ``to``'s (a key of :data:`ENDINGS`): ``out.h5`` for a PTU file. ``flag`` and ``allow`` are
    the options that give the name and that keep it all the same, for the message."""
    what, endings = ENDINGS[to]
    text = os.fspath(path)
    if not text or text.lower().endswith(endings):
        return          # (an empty name is refused as no file name, by check_output_path)
    stem, ending = os.path.splitext(text)
    named = " or ".join(f"*{end}" for end in endings)
    has = f"not *{ending}" if ending else "and this name has no ending"
    raise FormatError(f"{flag} {text}: {what} is named {named}, {has}: give {flag} "
                      f"{stem}{endings[0]}, or {allow} to keep the name")


def export_refusal(kind, mode, name):
    """Why a capture of ``kind`` (its ``mode``; None: of no kind) cannot go to the format called
    ``name``, in one line."""
    if kind is not None and kind.refusal:
        if not kind.exports:            # no format takes it: the refusal says why
            return kind.refusal
        return f"{article(mode)} capture cannot go to {name}: {kind.refusal}"
    if kind is not None and kind.exports:
        return (f"{article(mode)} capture cannot go to {name}, which holds photons one by one, "
                f"not histograms: export it to {' or '.join(e.upper() for e in kind.exports)} "
                f"(--to {kind.exports[0]})")
    return f"{article(mode)} capture cannot be exported"


def export_capture(capture, path, to):
    """Write ``capture`` to ``path`` in the format ``to`` (a key of :data:`FORMATS`); returns
    the number of records (PTU) or photons (Photon-HDF5) written. The file is written under
    a temporary name beside ``path`` and renamed when whole, so a refusal or a failure leaves
    ``path`` as it was."""
    if to not in FORMATS:
        raise FormatError(f"no export format {to!r}; the formats are {', '.join(FORMATS)}")
    kind = KINDS.get(capture.mode)
    name, write = FORMATS[to]
    if kind is None or to not in kind.exports:
        raise FormatError(f"{capture.path}: {export_refusal(kind, capture.mode, name)}")
    folder, base = os.path.split(os.path.abspath(path))
    partial = os.path.join(folder, f".{base}.{os.getpid()}.part")
    try:
        written = write(capture, partial)
        os.replace(partial, path)
    finally:
        if os.path.exists(partial):
            os.unlink(partial)
    return written


def read_file(path):
    """The capture in ``path``: a FLISS capture file (:func:`~fliss.host.fileformat.
    read_capture`), a PTU file (T3) or a Photon-HDF5 file (:mod:`.ptu`, :mod:`.photon_hdf5`),
    an HT3, PT3 or SPC file (:mod:`.tttr_foreign`, as are PTU files other programs wrote).
    Raises :exc:`ValueError` of one line for what cannot be read."""
    path = str(path)
    try:
        with open(path, "rb") as f:
            head = f.read(16)
    except OSError:
        head = b""                      # read_capture says why
    if head.startswith(_PTU) or (path.lower().endswith(".ptu") and
                                 not head.startswith(b"\x89HDF")):
        header = read_header(path)  # (a .ptu name without the mark: refused, saying so)
        if "FLISS_configuration" in header.tags:
            return read_ptu(path)
        return read_foreign(path, "ptu", header)
    kind = foreign_kind(path, head) if not head.startswith(b"\x89HDF") else None
    if kind is not None:
        return read_foreign(path, kind)
    if head.startswith(_PHU):
        raise FormatError(f"{path}: a PicoQuant histogram (PHU) file; fliss reads PTU files "
                          f"(T3 records), HT3, PT3 and SPC files, Photon-HDF5 files and FLISS "
                          f"capture files")
    if head.startswith(b"\x89HDF") and is_photon_hdf5(path):
        return read_photon_hdf5(path)
    return read_capture(path)
