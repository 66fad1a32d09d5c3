"""What a kind of data is, for the host: :class:`DataKind`, the slice that the capture, its file,
its exports and the live view find through :mod:`fliss.host.kinds`."""

from dataclasses import dataclass
from typing import Callable, NamedTuple, Optional, Tuple

import numpy as np

from ...hdl.registers import AcquisitionMode


__all__ = ["Seen", "DataKind", "extend"]


def extend(dataset, index, values):
    """Rows ``index …`` of the HDF5 dataset ``dataset``: ``values``, one a row (grown to
    hold them)."""
    values = np.asarray(values, dtype=dataset.dtype)
    dataset.resize(index + len(values), axis=0)
    dataset[index:index + len(values)] = values


class Seen(NamedTuple):
    """What the live view takes of an item: its frame number (None: not numbered, an event
    batch) and whether it is complete, the counts it adds to the sum (``(pixels, bins)``,
    None: nothing), the photons it counts, and whether it is the latest frame to draw."""
    frame: Optional[int]
    complete: bool
    counts: Optional[np.ndarray]
    photons: int
    latest: bool


@dataclass(frozen=True)
class DataKind:
    """One kind of data a capture holds: a *capture mode* (the file's ``mode`` attribute, the
    view's readout).

    Facts
    -----
    name : str
        The capture mode: ``"histogram"``, ``"image"``, ``"depth"``, ``"raw"``.
    rank : int
        Its place in lists of the kinds (choices, messages), lowest first.
    readout : AcquisitionMode
        The board's ``acquisition`` setting that makes it.
    packet : str
        The kind of data packet that carries it (:data:`fliss.hdl.protocol.DATA_PACKETS`);
        kinds of one packet share its assembler.
    item : type
        What the assembler returns for it (:class:`~fliss.host.stream.HistogramFrame`, ...).
    rows : str or None
        What rows of its file are called (``"histograms"``), None when it is not saved in
        frames (raw events, for a duration).
    format_version : int
        The capture file's ``format_version`` its files are written with.
    what : str
        What the view calls its data (``"per-pixel histograms"``).
    counted : bool
        Its items carry the photons counted (their rate is counts per second); False for
        depth frames, whose pace is in frames.
    imager : bool
        Its data has pixels that the view draws as a profile or an image.
    per_pixel : str or None
        The kind its data is saved as when the board's frames hold several pixels (or
        when asked to): histograms as ``"image"``.

    Slice
    -----
    assembler : type
        ``assembler(stream)``: turns its packets (``add(packet, time_s)``) into items, counted
        in ``stream.counters`` (a :class:`~fliss.host.stream.StreamAssembler`); ``flush()``
        gives what is in progress at the end. One per kind of packet. Its ``COUNTERS`` name
        the counters it keeps in the stream's (made from 0 for it), ``FRAMES`` the one of
        them that counts the frames it made (None: it makes no numbered frames).
    create : callable or None
        ``create(file, configuration, code_s)``: its datasets in a new capture file; returns
        the writer's state for :attr:`append`.
    fits : callable or None
        ``fits(file, item, state)``: whether the item fits the capture (its bins, pixels);
        one that does not is not stored.
    append : callable or None
        ``append(file, index, items, state, completes)``: rows ``index …``, one an item of
        ``items`` (each of which fits), in one write a dataset; ``completes`` False marks an
        item that never arrived (a blank row).
    blank : callable or None
        ``blank(number, configuration)``: the row of a frame that never arrived.
    read : callable
        ``read(file, group_of, rows_of, problems)``: a dict of
        :class:`~fliss.host.fileformat.Capture` fields read from its datasets;
        ``group_of(file, name)`` is a group that must be there, ``rows_of(dataset, problems)``
        the rows of a dataset that can be read.
    tally : callable
        ``tally(totals, item)``: adds a saved item to a capture's totals (``events``,
        ``detections``, ``highest``, ``threshold`` of
        :class:`fliss.host.acquisition.CaptureResult`).
    replay : callable
        ``replay(capture)``: the items a board sent for a capture read back
        (:class:`~fliss.host.fileformat.Capture`), as the assembler made them: what the live
        view's replays hand it.
    seen : callable
        ``seen(item, shift)``: what the live view (:class:`fliss.host.view.feed.Feed`) takes of
        an item, a :class:`Seen`; ``shift`` is the view's bin shift.
    exports : tuple of str
        The export formats (:data:`fliss.host.formats.FORMATS`) that take it.
    refusal : str
        Why an export format that does not take it does not: the refusal's message when no
        format takes it, its reason after "cannot go to FORMAT" when some do (empty: the
        message names those).
    """
    name: str
    rank: int
    readout: AcquisitionMode
    packet: str
    assembler: type
    item: type
    rows: Optional[str]
    format_version: int
    what: str
    counted: bool
    imager: bool
    read: Callable
    tally: Callable
    replay: Callable
    seen: Callable
    per_pixel: Optional[str] = None
    create: Optional[Callable] = None
    fits: Optional[Callable] = None
    append: Optional[Callable] = None
    blank: Optional[Callable] = None
    exports: Tuple[str, ...] = ()
    refusal: str = ""

    @property
    def framed(self) -> bool:
        """Saved in frames, one row each (a number of acquisitions), not for a duration."""
        return self.rows is not None
