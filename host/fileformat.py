"""Capture files: HDF5 (h5py), schema in ``docs/file-format.md``.

:class:`CaptureWriter` writes a capture as it arrives (histograms and events are appended and
flushed, so a capture cut short by a dead board or a crash still leaves a readable file);
:func:`read_capture` reads one back into a :class:`Capture`.
"""

import datetime
import json
from dataclasses import dataclass, field

import h5py
import numpy as np

from .. import __version__
from ..hdl.event import TDC_LSB_S, TIMESTAMP_BITS
from ..hdl.registers import BY_NAME, REGISTERS, TdcSource
from ..sim.event import EVENT_DTYPE


__all__ = ["FORMAT", "FORMAT_VERSION", "CaptureWriter", "Capture", "read_capture"]


#: Value of the root attribute ``format``.
FORMAT = "fliss-capture"
#: Version of this schema; readers refuse newer major versions.
FORMAT_VERSION = 2

_FLUSH_S = 1.0


class CaptureWriter:
    """Writes one capture file.

    Parameters
    ----------
    path : str
    mode : str
        ``"histogram"`` or ``"raw"``.
    identity : dict
        The board's identity (``protocol``, ``gateware_version``, ``registers``, ``clock_hz``,
        ``baud``).
    configuration : dict
        Register values by name, as read from the board before the start.
    port : str
    """

    def __init__(self, path, *, mode, identity, configuration, port=""):
        self.path = str(path)
        self.file = h5py.File(self.path, "w")
        f = self.file
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        f.attrs["host_version"] = __version__
        f.attrs["created_utc"] = datetime.datetime.now(datetime.timezone.utc).isoformat()
        f.attrs["port"] = port
        f.attrs["mode"] = mode
        f.attrs["end_reason"] = "running"
        f.attrs["complete"] = False
        group = f.create_group("identity")
        for name, value in identity.items():
            group.attrs[name] = value
        group = f.create_group("configuration")
        for name, value in configuration.items():
            group.attrs[name] = np.uint32(value)
        group.attrs["units"] = json.dumps({name: BY_NAME[name].unit for name in configuration})
        group = f.create_group("histograms")
        self._bins = None
        self.histograms = 0
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
        self._flushed = 0.0

    def _histogram_datasets(self, bins):
        group = self.file["histograms"]
        group.create_dataset("counts", shape=(0, bins), maxshape=(None, bins), dtype=np.uint32,
                             chunks=(max(1, min(64, (1 << 16) // bins)), bins),
                             compression="gzip", compression_opts=1)
        for name, dtype in (("frame", np.uint32), ("shift", np.uint8),
                            ("time_s", np.float64), ("complete", np.bool_),
                            ("missing_bins", np.uint32)):
            group.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(1024,))
        self._bins = bins

    def add_histogram(self, frame):
        """Append a :class:`~fliss.host.stream.HistogramFrame`; returns False (and stores
        nothing) if its bin count differs from the first one's."""
        bins = len(frame.counts)
        if self._bins is None:
            self._histogram_datasets(bins)
        if bins != self._bins:
            return False
        group = self.file["histograms"]
        index = self.histograms
        for name in ("counts", "frame", "shift", "time_s", "complete", "missing_bins"):
            group[name].resize(index + 1, axis=0)
        group["counts"][index] = frame.counts
        group["frame"][index] = frame.frame
        group["shift"][index] = frame.shift
        group["time_s"][index] = frame.time_s
        group["complete"][index] = frame.complete
        group["missing_bins"][index] = frame.missing_bins
        self.histograms += 1
        self._maybe_flush(frame.time_s)
        return True

    def add_events(self, batch):
        """Append an :class:`~fliss.host.stream.EventBatch`."""
        group = self.file["events"]
        count = len(batch.events)
        group["events"].resize(self.events + count, axis=0)
        group["events"][self.events:] = batch.events
        group["batch_offset"].resize(self.batches + 1, axis=0)
        group["batch_offset"][self.batches] = self.events
        group["batch_time_s"].resize(self.batches + 1, axis=0)
        group["batch_time_s"][self.batches] = batch.time_s
        self.events += count
        self.batches += 1
        self._maybe_flush(batch.time_s)

    def _maybe_flush(self, now):
        if now - self._flushed > _FLUSH_S:
            self.file.flush()
            self._flushed = now

    def set_counters(self, name, counters):
        """Store a dict of counters as the attributes of ``/counters/<name>``."""
        group = self.file["counters"].require_group(name)
        for key, value in counters.items():
            group.attrs[key] = value

    def close(self, end_reason="completed", *, complete=True, **attrs):
        if self.file is None:
            return
        self.file.attrs["end_reason"] = end_reason
        self.file.attrs["complete"] = complete
        self.file.attrs["closed_utc"] = datetime.datetime.now(datetime.timezone.utc).isoformat()
        for key, value in attrs.items():
            self.file.attrs[key] = value
        self.file.close()
        self.file = None

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

    ``histograms`` is ``(N, bins)`` (``uint32``); ``events`` an ``EVENT_DTYPE`` array; the
    counters are dicts by group name (``link``, ``stream``, ``board_start``, ``board_end``).
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

    @property
    def mode(self):
        return self.attrs.get("mode", "histogram")

    @property
    def clock_hz(self):
        return int(self.identity.get("clock_hz", 0)) or None

    @property
    def shift(self):
        if len(self.shifts):
            return int(self.shifts[0])
        return int(self.configuration.get("bin_shift", 0))

    @property
    def code_s(self):
        """Width of one timestamp code in seconds: 50 ps (sensor) or a clock cycle (coarse)."""
        if self.configuration.get("tdc_source") == TdcSource.COARSE.value and self.clock_hz:
            return 1.0 / self.clock_hz
        return TDC_LSB_S

    @property
    def bin_s(self):
        return self.code_s * (1 << self.shift)

    def total_histogram(self, complete_only=True):
        """Sum of the histograms (the complete ones by default); for a raw capture, the
        histogram of the events' timestamps with the configured bin shift."""
        if self.mode == "raw" or not len(self.histograms):
            bins = (1 << TIMESTAMP_BITS) >> self.shift
            stamps = self.events["timestamp"].astype(np.int64) >> self.shift
            return np.bincount(stamps, minlength=bins)[:bins].astype(np.int64)
        rows = self.histograms[self.complete] if complete_only else self.histograms
        return rows.sum(axis=0, dtype=np.int64)


def read_capture(path):
    """Read a capture file; raises :exc:`ValueError` for a file that is not one."""
    try:
        f = h5py.File(path, "r")
    except (OSError, FileNotFoundError) as error:
        raise ValueError(f"cannot read {path!r} as an HDF5 capture file ({error})") from None
    with f:
        if f.attrs.get("format") != FORMAT:
            raise ValueError(f"{path!r} is not a FLISS capture file")
        if int(f.attrs.get("format_version", 0)) > FORMAT_VERSION:
            raise ValueError(f"{path!r} has format version {f.attrs['format_version']}, newer "
                             f"than this fliss reads ({FORMAT_VERSION})")
        attrs = {key: _plain(value) for key, value in f.attrs.items()}
        identity = {key: _plain(value) for key, value in f["identity"].attrs.items()}
        configuration = {key: int(value) for key, value in f["configuration"].attrs.items()
                         if key != "units"}
        group = f["histograms"]
        if "counts" in group:
            histograms = group["counts"][()]
            frames, shifts = group["frame"][()], group["shift"][()]
            times, complete = group["time_s"][()], group["complete"][()]
        else:
            histograms = np.zeros((0, 0), dtype=np.uint32)
            frames = np.zeros(0, dtype=np.uint32)
            shifts = np.zeros(0, dtype=np.uint8)
            times = np.zeros(0)
            complete = np.zeros(0, dtype=bool)
        events = f["events"]["events"][()]
        batch_times = f["events"]["batch_time_s"][()]
        counters = {name: {key: _plain(value) for key, value in group.attrs.items()}
                    for name, group in f["counters"].items()}
    return Capture(str(path), attrs, identity, configuration, histograms, frames, shifts,
                   times, complete.astype(bool), events, batch_times, counters)


def _plain(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, bytes):
        return value.decode()
    return value


# Registers that are in every file, in address order (for readers without the map).
REGISTER_NAMES = tuple(register.name for register in REGISTERS)
