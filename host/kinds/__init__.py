"""The kinds of data a capture holds, one slice per kind (``docs/file-format.md``).

Each module here other than :mod:`.kind` is one kind of data: it defines ``KIND``, a
:class:`~.kind.DataKind` that holds its facts and its slice: the items its packets are assembled
into and the assembler, its datasets in a capture file (made, appended, read, a blank row for
a frame lost), what a capture counts of it and the export formats that take it. The capture
(:mod:`fliss.host.acquisition`, :mod:`fliss.host.rows`), the stream
(:mod:`fliss.host.stream`), the file (:mod:`fliss.host.fileformat`), the exports
(:mod:`fliss.host.formats`), the Python API and the live view find a kind here by its name
(the capture mode), never by testing the name themselves.

* :mod:`.histogram`: histograms (HISTOGRAM and HISTOGRAM_COMPACT chunks, ``/histograms``);
* :mod:`.image`: per-pixel histograms (the same chunks, ``/image``);
* :mod:`.depth`: depth frames (DEPTH packets, ``/depth``);
* :mod:`.raw`: raw events (EVENTS packets, ``/events``).

A new kind is a new module here: every module of this package is read for its ``KIND``. A new
kind of data from the board is five files: its packet and readout in :mod:`fliss.hdl.protocol`
(``PacketType``, ``AcquisitionMode``, ``DATA_PACKETS`` and the payload's layout), its packetizer
in :mod:`fliss.hdl.packets`, its wiring in :mod:`fliss.hdl.top`, its module here, and the model
board's producer in :mod:`fliss.sim.boards.producers`.
"""

import importlib
import pkgutil

from ...hdl.registers import AcquisitionMode
from .kind import DataKind


__all__ = ["DataKind", "KINDS", "DEFAULT", "kind_of", "for_mode", "of_capture", "article",
           "names", "mode_of", "assemblers"]


def _discover():
    found = []
    for module in pkgutil.iter_modules(__path__):
        if module.name != "kind":
            found.append(importlib.import_module(f".{module.name}", __name__).KIND)
    return {kind.name: kind for kind in sorted(found, key=lambda kind: kind.rank)}


#: The kinds by name (capture mode), in their order.
KINDS = _discover()


def kind_of(mode: str) -> DataKind:
    """The kind of capture mode ``mode``; :exc:`ValueError` of one line for another name."""
    try:
        return KINDS[mode]
    except KeyError:
        raise ValueError(f"no kind of data {mode!r}; the kinds are "
                         f"{', '.join(KINDS)}") from None


#: The kind of a capture file that names none (the first kind: histograms), and of one whose
#: mode is of no kind (another program's), which is read as that kind's.
DEFAULT = next(iter(KINDS))


def for_mode(mode) -> DataKind:
    """The kind of a capture file's ``mode`` (:data:`DEFAULT`'s for one of no kind)."""
    return KINDS.get(mode, KINDS[DEFAULT])


def of_capture(capture) -> DataKind:
    """The kind of a capture read back (:class:`~fliss.host.fileformat.Capture`)."""
    return for_mode(capture.mode)


def article(name: str) -> str:
    """``"an image"``, ``"a depth"``: a kind's name with its article."""
    return f"{'an' if name[:1] in 'aeiou' else 'a'} {name}"


def names(test, joined="and") -> str:
    """The names of the kinds for which ``test(kind)`` holds, as text: ``"image and
    depth"``, ``"histogram, image and depth"``."""
    found = [name for name, kind in KINDS.items() if test(kind)]
    return " ".join(filter(None, [", ".join(found[:-1]), joined if len(found) > 1 else "",
                                  found[-1]]))


def mode_of(readout, pixel_bits=0, image=None) -> str:
    """The capture mode of the board's readout (an ``AcquisitionMode`` or its name) when a
    frame holds ``2**pixel_bits`` pixels: a kind that has a per-pixel form is saved as that
    when ``image`` is True, or None and a frame has several pixels."""
    if isinstance(readout, str):
        readout = AcquisitionMode[readout.upper()]
    kind = next(kind for kind in KINDS.values() if kind.readout == readout)
    if kind.per_pixel is not None and (image or (image is None and pixel_bits)):
        return kind.per_pixel
    return kind.name


def assemblers(stream) -> dict:
    """An assembler of each kind of data packet (:data:`fliss.protocol.packets.KIND`), for
    the stream assembler ``stream``; kinds of one packet share it."""
    made = {}
    for kind in KINDS.values():
        if kind.packet not in made:
            made[kind.packet] = kind.assembler(stream)
    return made
