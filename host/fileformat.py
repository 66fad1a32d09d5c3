"""Capture files: HDF5 (h5py), schema in ``docs/file-format.md``.

:class:`CaptureWriter` writes a capture as it arrives, in HDF5's single-writer mode (SWMR), which
keeps the file readable at every moment: a capture cut short by a dead board, a crash or
``kill -9`` leaves a file with everything flushed before, at most :data:`FLUSH_S` of data lost.
:func:`read_capture` reads one back into a :class:`Capture`, and reads what can be read of a file
that was damaged (:attr:`Capture.problems`).
"""

import datetime
import json
import os
import time
from dataclasses import dataclass, field
from typing import Optional

import h5py
import numpy as np

from .. import __version__
from .filespace import Room
from ..hdl.event import TDC_LSB_S, TIMESTAMP_BITS
from ..hdl.registers import BY_NAME
from ..hdl.codes import code_s as timestamp_code_s
from ..protocol.events import EVENT_DTYPE
from .kinds import DEFAULT, KINDS, for_mode, kind_of
from .kinds.kind import extend


__all__ = ["FORMAT", "FORMAT_VERSION", "FLUSH_S", "RUNNING", "CaptureWriter", "Capture",
           "read_capture"]


#: Value of the root attribute ``format``.
FORMAT = "fliss-capture"
#: Version of this schema; readers refuse newer major versions. Each kind of data writes its
#: files with its own version (:attr:`fliss.host.kinds.DataKind.format_version`): histogram and
#: raw files still as version 2 (unchanged), which older readers take; image and depth files
#: (the imager's groups) as version 3.
FORMAT_VERSION = 3

#: Most seconds between two flushes of a capture file: what a ``kill -9`` can cost.
FLUSH_S = 0.5

#: ``end_reason`` of a file that the writer never closed (still being written, or killed).
RUNNING = "running"

#: Most frame rows, and most events, kept by the writer before it writes them (in one write a
#: dataset: HDF5 takes about as long for a row as for a batch of them).
BATCH_ROWS = 256
BATCH_EVENTS = 1 << 16


class CaptureWriter:
    """Writes one capture file.

    Every attribute and dataset is made when the file is opened; then the file goes into HDF5's
    single-writer mode (SWMR), in which it is consistent on disk at every moment, and rows are
    appended in batches (of up to :data:`BATCH_ROWS` frames or :data:`BATCH_EVENTS` events)
    and flushed at least every :data:`FLUSH_S` seconds. :meth:`close` opens it again
    normally to store the end: ``end_reason``, the counters of :meth:`set_counters`.

    Parameters
    ----------
    path : str
    mode : str
        The kind of data (:data:`fliss.host.kinds.KINDS`): ``"histogram"``, ``"raw"``,
        ``"image"`` (per-pixel histograms, ``/image``) or ``"depth"`` (depth frames,
        ``/depth``).
    identity : dict
        The board's identity (``protocol``, ``gateware_version``, ``registers``, ``clock_hz``,
        ``baud``).
    configuration : dict
        Register values by name, as read from the board before the start; in histogram mode
        its ``bin_shift`` sets the number of bins.
    port : str
    attrs : dict, optional
        More root attributes (``integration_s``, ``acquisitions_requested``, ...).
    flush_s : float
        Most seconds between flushes.
    """

    def __init__(self, path, *, mode, identity, configuration, port="", attrs=None,
                 flush_s=FLUSH_S):
        self.path = str(path)
        self.flush_s = flush_s
        self._counters = {}
        self.kind = kind_of(mode)
        self.file = h5py.File(self.path, "w", libver=("v110", "latest"))
        try:
            self._create(mode, identity, configuration, port, attrs or {})
            self.file.swmr_mode = True
        except BaseException:
            self.file.close()
            self.file = None
            raise
        self._flushed = time.monotonic()
        self._rows, self._batches = [], []    # (item, complete), EventBatch: not yet written
        self._written = self._events_written = 0
        self._room = Room(self.file, self.path)     # FileFull before a write that fails

    def _create(self, mode, identity, configuration, port, attrs):
        f = self.file
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = self.kind.format_version
        f.attrs["host_version"] = __version__
        f.attrs["created_utc"] = datetime.datetime.now(datetime.timezone.utc).isoformat()
        f.attrs["port"] = port
        f.attrs["mode"] = mode
        f.attrs["end_reason"] = RUNNING
        f.attrs["complete"] = False
        for key, value in attrs.items():
            f.attrs[key] = value
        group = f.create_group("identity")
        for name, value in identity.items():
            group.attrs[name] = value
        group = f.create_group("configuration")
        # Never the key: write-only registers (they read 0 anyway) are left out.
        configuration = {name: value for name, value in configuration.items()
                         if not BY_NAME[name].write_only}
        for name, value in configuration.items():
            group.attrs[name] = np.uint32(value)
        group.attrs["units"] = json.dumps({name: BY_NAME[name].unit for name in configuration})
        # Every file has /histograms (empty but in histogram captures) and /events (empty but
        # in raw captures); the kind adds its datasets.
        f.create_group("histograms")
        self.histograms = 0
        self.mode = mode
        code_s = (timestamp_code_s(configuration, identity["clock_hz"])
                  if identity.get("clock_hz") else TDC_LSB_S)
        self._state = None if self.kind.create is None else \
            self.kind.create(f, configuration, code_s)
        group = f.create_group("events")
        group.create_dataset("events", shape=(0,), maxshape=(None,), dtype=EVENT_DTYPE,
                             chunks=(1 << 14,))
        group.create_dataset("batch_offset", shape=(0,), maxshape=(None,), dtype=np.uint64,
                             chunks=(1024,))
        group.create_dataset("batch_time_s", shape=(0,), maxshape=(None,), dtype=np.float64,
                             chunks=(1024,))
        self.events = 0
        self.batches = 0
        f.create_group("counters")

    def add_frame(self, frame, *, complete=True):
        """Append a frame as its kind of data stores it (:attr:`fliss.host.kinds.DataKind.
        append`): a :class:`~fliss.host.stream.HistogramFrame` (histogram and image modes) or
        a :class:`~fliss.host.stream.DepthFrame` (depth mode); returns False (and stores
        nothing) if it does not fit the capture (another split, another mode). ``complete``
        False marks a depth frame that never arrived (a histogram says it itself)."""
        kind = self.kind
        if kind.append is None or (kind.fits and not kind.fits(self.file, frame, self._state)):
            return False
        self._room.check(sum(value.nbytes for value in vars(frame).values()
                             if isinstance(value, np.ndarray)))
        self._rows.append((frame, complete))
        self.histograms += 1
        if len(self._rows) >= BATCH_ROWS:
            self._write_rows()
        self._maybe_flush()
        return True

    #: Appends a :class:`~fliss.host.stream.HistogramFrame` (the name of former versions).
    add_histogram = add_frame

    def add_events(self, batch):
        """Append an :class:`~fliss.host.stream.EventBatch`."""
        self._room.check(batch.events.nbytes)
        self._batches.append(batch)
        self.events += len(batch.events)
        self.batches += 1
        if self.events - self._events_written >= BATCH_EVENTS:
            self._write_events()
        self._maybe_flush()

    def _write_rows(self):
        if self._rows:
            items, completes = zip(*self._rows)
            self._rows = []
            self.kind.append(self.file, self._written, list(items), self._state,
                             list(completes))
            self._written += len(items)

    def _write_events(self):
        if not self._batches:
            return
        batches, self._batches = self._batches, []
        group = self.file["events"]
        first = self.batches - len(batches)
        offsets = self._events_written + np.cumsum([0] + [len(b.events) for b in batches[:-1]])
        extend(group["events"], self._events_written,
               np.concatenate([batch.events for batch in batches]))
        extend(group["batch_offset"], first, offsets)
        extend(group["batch_time_s"], first, [batch.time_s for batch in batches])
        self._events_written = self.events

    def flush(self):
        """Write everything appended so far to the disk."""
        self._write_rows()
        self._write_events()
        self.file.flush()
        self._flushed = time.monotonic()
        self._room.flushed()

    def _maybe_flush(self):
        if time.monotonic() - self._flushed >= self.flush_s:
            self.flush()

    def set_counters(self, name, counters):
        """Counters (a dict) to store as the attributes of ``/counters/<name>`` on
        :meth:`close`."""
        self._counters[name] = dict(counters)

    def close(self, end_reason="completed", *, complete=True, **attrs):
        """Close the file, then open it again (out of single-writer mode) to store
        ``end_reason``, ``complete``, ``closed_utc``, the counters and ``attrs``."""
        if self.file is None:
            return
        try:
            self._write_rows()
            self._write_events()
        finally:
            self.file.close()
            self.file = None
        with h5py.File(self.path, "r+") as f:
            for name, counters in self._counters.items():
                group = f["counters"].require_group(name)
                for key, value in counters.items():
                    group.attrs[key] = value
            f.attrs["end_reason"] = end_reason
            f.attrs["complete"] = complete
            f.attrs["closed_utc"] = datetime.datetime.now(datetime.timezone.utc).isoformat()
            for key, value in attrs.items():
                f.attrs[key] = value

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        if exc[0] is not None:
            self.close(f"error: {exc[1]}", complete=False)
        else:
            self.close()


@dataclass
class Capture:
    """A capture file read back.

    ``histograms`` is ``(N, bins)`` (``uint32``), ``(N, pixels, bins)`` in image mode;
    ``pixels`` the pixel addresses (image and depth modes); ``depth`` the depth frames' arrays
    by name (``position``, ``depth_m``, ``height``, ``background``, ``detected``, each
    ``(N, pixels)``; depth mode, else None); ``events`` an ``EVENT_DTYPE`` array; the
    counters are dicts by group name (``link``, ``stream``, ``board_start``, ``board_end``);
    ``problems`` says what of a file cut short could not be read (empty for a whole file).
    """
    path: str
    attrs: dict
    identity: dict
    configuration: dict
    histograms: np.ndarray
    frames: np.ndarray
    shifts: np.ndarray
    times_s: np.ndarray
    complete: np.ndarray
    events: np.ndarray
    batch_times_s: np.ndarray
    counters: dict = field(default_factory=dict)
    #: What could not be read, or why the file is not whole (one sentence each).
    problems: list = field(default_factory=list)
    #: Pixel addresses (image and depth captures).
    pixels: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    #: Depth frames' arrays by name (depth captures).
    depth: Optional[dict] = None

    @property
    def mode(self):
        return self.attrs.get("mode", DEFAULT)

    @property
    def clock_hz(self):
        return int(self.identity.get("clock_hz", 0)) or None

    @property
    def calibration_table(self):
        """The fine TDC's calibration table the board held (raw code -> 12.5 ps units), or
        None (a capture without the fine TDC)."""
        table = self.attrs.get("calibration_table")
        return None if table is None else np.asarray(table, dtype=np.int64)

    @property
    def shift(self):
        if len(self.shifts):
            return int(self.shifts[0])
        return int(self.configuration.get("bin_shift", 0))

    @property
    def code_s(self):
        """Width of one timestamp code in seconds: 50 ps (sensor), a clock cycle (coarse), the
        fine TDC's LSB (:func:`fliss.hdl.codes.code_s`)."""
        if self.clock_hz:
            return timestamp_code_s(self.configuration, self.clock_hz)
        return TDC_LSB_S

    @property
    def bin_s(self):
        return self.code_s * (1 << self.shift)

    def total_histogram(self, complete_only=True):
        """Sum of the histograms (the complete ones by default); for a raw capture, the
        histogram of the events' timestamps with the configured bin shift."""
        kind = KINDS.get(self.mode)
        if (kind is not None and not kind.framed) or not len(self.histograms):
            bins = (1 << TIMESTAMP_BITS) >> self.shift
            stamps = self.events["timestamp"].astype(np.int64) >> self.shift
            return np.bincount(stamps, minlength=bins)[:bins].astype(np.int64)
        rows = self.histograms[self.complete] if complete_only else self.histograms
        return rows.sum(axis=0, dtype=np.int64)


def read_capture(path):
    """Read a capture file.

    Raises :exc:`ValueError` with one line for what is not a capture file (missing, a folder,
    empty, not HDF5, another format, a newer version, groups missing). Of a file cut short (the
    writer was killed, or a file of an older fliss damaged by a crash) it returns every row that
    can be read and says what it left out in :attr:`Capture.problems`.
    """
    path = str(path)
    if not os.path.exists(path):
        raise ValueError(f"no such file: {path}")
    if os.path.isdir(path):
        raise ValueError(f"{path} is a folder, not a capture file")
    if not os.path.isfile(path):
        raise ValueError(f"{path} is not a regular file (a device or a pipe?), not a capture "
                         f"file")
    if os.path.getsize(path) == 0:
        raise ValueError(f"{path} is empty, not a capture file")
    size = os.path.getsize(path)
    f = _open(path)
    try:
        with f:
            capture = _read_open(path, f)
    except (ValueError, KeyError, OSError, RuntimeError) as error:
        _check_whole(path, size)        # cut short meanwhile: says so first
        if isinstance(error, ValueError):
            raise
        raise ValueError(f"{path!r} cannot be read ({str(error).splitlines()[0]})") from None
    _check_whole(path, size)
    return capture


def _read_open(path, f):
    """The capture in ``f``, the open HDF5 file at ``path``."""
    if _plain(f.attrs.get("format")) != FORMAT:
        raise ValueError(f"{path!r} is not a FLISS capture file")
    version = _plain(f.attrs.get("format_version", 0))
    if not isinstance(version, int):
        raise ValueError(f"{path!r} has format version {version!r}, not a number: it is "
                         f"damaged or not written by fliss")
    if version > FORMAT_VERSION:
        raise ValueError(f"{path!r} has format version {version}, newer than this fliss "
                         f"reads ({FORMAT_VERSION}); update fliss")
    try:
        return _read(path, f)
    except (KeyError, TypeError, ValueError, AttributeError) as error:
        detail = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise ValueError(f"{path!r} claims the FLISS capture format but is damaged or not "
                         f"written by fliss ({detail})") from None


def _check_whole(path, size):
    """Refuse what was read of ``path`` if the file is now shorter than the ``size`` bytes it
    had when it was opened: another program cut it short (or replaced it) meanwhile, and HDF5
    read garbage, or zeros past its end. (Removed meanwhile, it was read whole: an open file
    keeps its data.)"""
    try:
        now = os.path.getsize(path)
    except OSError:
        return
    if now < size:
        raise ValueError(f"{path!r} was cut short while it was read (from {size} to {now} "
                         f"bytes): nothing of it is used")


def _open(path):
    try:
        return h5py.File(path, "r")
    except OSError as error:
        if "already open for write" not in str(error):
            reason = str(error)
            if "(" in reason:
                reason = reason[reason.rindex("(") + 1:].rstrip(")")
            what = "is not an HDF5 file" if "signature" in reason else \
                "cannot be read as an HDF5 file"
            raise ValueError(f"{path!r} {what} ({reason}), not a capture file") from None
    # Marked open by a writer in single-writer mode: being written, or the writer was killed.
    try:
        return h5py.File(path, "r", swmr=True)
    except OSError as error:
        raise ValueError(f"cannot read {path!r}: {error}") from None


def _group(f, name):
    if not isinstance(f.get(name), h5py.Group):
        raise ValueError(f"no /{name} group")
    return f[name]


def _rows(dataset, problems):
    """The rows of ``dataset`` up to the first that cannot be read (a chunk that a killed writer
    left unreadable), with a note in ``problems`` for those left out."""
    try:
        return dataset[()]
    except OSError:
        pass
    step = dataset.chunks[0] if dataset.chunks else 1
    pieces, start, total = [], 0, dataset.shape[0]
    while start < total:
        try:
            pieces.append(dataset[start:start + step])
        except OSError as error:
            problems.append(f"rows {start} to {total - 1} of {dataset.name} cannot be read "
                            f"({str(error).split('(')[-1].rstrip(')')}) and are left out")
            break
        start += step
    if not pieces:
        return dataset[0:0] if total else dataset[()]
    return np.concatenate(pieces)


def _read(path, f):
    problems = []
    attrs = {key: _plain(value) for key, value in f.attrs.items()}
    if attrs.get("end_reason") == RUNNING:
        problems.append("its writer never closed it (the capture was killed, or is still "
                        "running): what was flushed is read, its counters are missing")
    identity = {key: _plain(value) for key, value in _group(f, "identity").attrs.items()}
    configuration = {key: int(value) for key, value in _group(f, "configuration").attrs.items()
                     if key != "units"}
    _group(f, "histograms")
    # (a mode of no kind, from another program: its /histograms, as of a histogram capture)
    kind = for_mode(attrs.get("mode"))
    rows = {"histograms": np.zeros((0, 0), dtype=np.uint32),
            "frames": np.zeros(0, dtype=np.uint32), "shifts": np.zeros(0, dtype=np.uint8),
            "times_s": np.zeros(0), "complete": np.zeros(0, dtype=bool),
            "pixels": np.zeros(0, dtype=np.int64), "depth": None}
    rows.update(kind.read(f, _group, _rows, problems))
    events_group = _group(f, "events")
    events = _rows(events_group["events"], problems)
    batch_times = _rows(events_group["batch_time_s"], problems)
    counters = {name: {key: _plain(value) for key, value in group.attrs.items()}
                for name, group in _group(f, "counters").items()}
    return Capture(path, attrs, identity, configuration, rows["histograms"], rows["frames"],
                   rows["shifts"], rows["times_s"], rows["complete"].astype(bool), events,
                   batch_times, counters, problems, rows["pixels"], rows["depth"])


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, bytes):
        return value.decode()
    return value
