"""Histograms (capture mode ``"histogram"``): HISTOGRAM and HISTOGRAM_COMPACT chunks assembled
into whole frames, one row of ``/histograms`` each; exported to PTU."""

import math
import time
from dataclasses import dataclass

import numpy as np

from ...hdl.event import TIMESTAMP_BITS
from ...hdl.registers import AcquisitionMode
from ...protocol.histograms import MalformedChunk, decode_chunk
from .kind import DataKind, Seen, extend


__all__ = ["HistogramFrame", "HistogramAssembler", "ROW_DATASETS", "KIND"]


@dataclass
class HistogramFrame:
    """One histogram as read out by the board.

    The frame holds ``P = 2**pixel_bits`` pixels (addresses ``first_pixel …``) of
    ``N = 2**13 >> shift`` bins each; ``counts`` has the ``P * N`` bins, pixel after pixel
    (:attr:`image` is the same as a ``(P, N)`` array). Bins of chunks that never arrived are 0
    and ``complete`` is False. ``time_s`` is the host's receive time (``time.time()``) of its
    last chunk.
    """
    frame: int
    shift: int
    counts: np.ndarray
    complete: bool
    missing_bins: int
    time_s: float
    pixel_bits: int = 0
    first_pixel: int = 0

    @property
    def image(self) -> np.ndarray:
        """``counts`` as ``(pixels, bins)``."""
        return self.counts.reshape(1 << self.pixel_bits, -1)


class HistogramAssembler:
    """Whole histograms from HISTOGRAM and HISTOGRAM_COMPACT chunks (both forms fill the same
    frame), counted in the stream's ``counters`` (:class:`~fliss.host.stream.StreamCounters`).

    A frame is finished by its ``last`` chunk or by the first chunk of another frame (or of
    other settings: bin shift, pixel split); a frame that misses chunks is still returned, with
    ``complete`` False, and a jump in frame numbers counts the frames lost in between. A chunk
    that does not fit its frame is counted in ``malformed`` and dropped."""

    #: Its counters in the stream's (:class:`~fliss.host.stream.StreamCounters`), and the one
    #: that counts the frames it made.
    COUNTERS = ("histogram_chunks", "frames", "incomplete_frames", "lost_frames",
                "missing_bins")
    FRAMES = "frames"

    def __init__(self, stream):
        self.stream = stream
        self._frame = None
        self._settings = None
        self._counts = None
        self._filled = None
        self._next_frame = None

    def add(self, packet, time_s):
        counters = self.stream.counters
        out = []
        try:
            chunk = decode_chunk(packet.type, packet.payload)
        except MalformedChunk:
            counters.malformed += 1
            return out
        frame, first, counts = chunk.frame, chunk.first_bin, chunk.counts
        settings = (chunk.shift, chunk.pixel_bits, chunk.first_pixel)
        counters.histogram_chunks += 1
        if self._frame is not None and (frame != self._frame or settings != self._settings):
            out.append(self._finish(time_s))
        if self._frame is None:
            if self._next_frame is not None and frame != self._next_frame:
                counters.lost_frames += (frame - self._next_frame) % (1 << 32)
            self._frame, self._settings = frame, settings
            self._counts = np.zeros(chunk.bins, dtype=np.uint32)
            self._filled = np.zeros(chunk.bins, dtype=bool)
        self._counts[first:first + len(counts)] = counts
        self._filled[first:first + len(counts)] = True
        if chunk.last:
            self.stream.frames_ended = (frame + 1) % (1 << 32)
            out.append(self._finish(time_s))
        return out

    def _finish(self, time_s):
        counters = self.stream.counters
        missing = int(np.count_nonzero(~self._filled))
        shift, pixel_bits, first_pixel = self._settings
        result = HistogramFrame(self._frame, shift, self._counts, missing == 0, missing,
                                time_s, pixel_bits, first_pixel)
        counters.frames += 1
        if missing:
            counters.incomplete_frames += 1
            counters.missing_bins += missing
        self._next_frame = (self._frame + 1) % (1 << 32)
        self._frame = self._counts = self._filled = None
        return result

    def flush(self, time_s=None):
        """Finish the frame in progress (at the end of a stream); returns it in a list."""
        if self._frame is None:
            return []
        return [self._finish(time.time() if time_s is None else time_s)]


#: Datasets of ``/histograms``, one row per histogram; ``complete`` is False where never
#: written.
ROW_DATASETS = (("frame", np.uint32), ("shift", np.uint8), ("time_s", np.float64),
                ("complete", np.bool_), ("missing_bins", np.uint32))


def _bins(configuration):
    return (1 << TIMESTAMP_BITS) >> int(configuration.get("bin_shift", 0))


def create(file, configuration, code_s):
    """``/histograms/counts`` and its row datasets; returns the bins of a histogram."""
    group, bins = file["histograms"], _bins(configuration)
    group.create_dataset("counts", shape=(0, bins), maxshape=(None, bins), dtype=np.uint32,
                         chunks=(max(1, min(64, (1 << 16) // bins)), bins),
                         compression="gzip", compression_opts=1)
    for name, dtype in ROW_DATASETS:
        group.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(1024,))
    return bins


def fits(file, frame, bins):
    """Whether ``frame`` has the capture's bin count (rows of another are not stored)."""
    return hasattr(frame, "counts") and len(frame.counts) == bins


def append(file, index, frames, bins, completes):
    """Rows ``index …`` of ``/histograms``, one a frame of ``frames`` (which :func:`fits`; a
    histogram says itself whether it is complete)."""
    group = file["histograms"]
    columns = {"counts": np.stack([frame.counts for frame in frames]),
               "frame": [frame.frame for frame in frames],
               "shift": [frame.shift for frame in frames],
               "time_s": [frame.time_s for frame in frames],
               "missing_bins": [frame.missing_bins for frame in frames],
               "complete": [frame.complete for frame in frames]}
    # The rows' data first, then ``complete`` (its fill value False marks a row whose
    # data never reached the disk).
    for name in ("counts",) + tuple(name for name, _ in ROW_DATASETS):
        extend(group[name], index, columns[name])


def blank(number, configuration):
    """The row of a histogram that never arrived: zeros, marked incomplete."""
    bins = _bins(configuration)
    shift = int(configuration.get("bin_shift", 0))
    return HistogramFrame(number, shift, np.zeros(bins, np.uint32), False, bins, math.nan)


def read(file, group_of, rows_of, problems):
    """The rows of ``/histograms`` (none in a capture of another kind that has the group
    empty)."""
    group = group_of(file, "histograms")
    if "counts" not in group:
        return {}
    noted = len(problems)
    columns = {"counts": rows_of(group["counts"], problems)}
    for name, _ in ROW_DATASETS:
        columns[name] = rows_of(group[name], problems) if name in group else None
    for name in ("frame", "shift", "time_s", "complete"):
        if columns[name] is None:
            raise ValueError(f"no /histograms/{name}")
    rows = min(len(column) for column in columns.values() if column is not None)
    if len(problems) == noted and any(len(column) > rows for column in columns.values()
                                      if column is not None):
        problems.append(f"histograms after the first {rows} are incomplete on disk and "
                        f"left out")
    return {"histograms": columns["counts"][:rows], "frames": columns["frame"][:rows],
            "shifts": columns["shift"][:rows], "times_s": columns["time_s"][:rows],
            "complete": columns["complete"][:rows]}


def _split_of(capture):
    pixels = capture.pixels
    first = int(pixels[0]) if len(pixels) else 0
    pixel_bits = int(len(pixels)).bit_length() - 1 if len(pixels) else 0
    return first, pixel_bits


def frame_rows(capture):
    """``(index, frame, complete, shift, time_s)`` of each row of a framed capture."""
    for index in range(len(capture.frames)):
        frame, complete = int(capture.frames[index]), bool(capture.complete[index])
        shift = int(capture.shifts[index]) if len(capture.shifts) else capture.shift
        time_s = float(capture.times_s[index]) if len(capture.times_s) else 0.0
        yield index, frame, complete, shift, time_s


def replay(capture):
    """The :class:`HistogramFrame` of each row of ``capture`` (of each pixel's histograms
    where it has several)."""
    first, pixel_bits = _split_of(capture)
    for index, frame, complete, shift, time_s in frame_rows(capture):
        counts = np.asarray(capture.histograms[index])
        yield HistogramFrame(frame, shift, counts.reshape(-1), complete, 0, time_s,
                             pixel_bits if counts.ndim > 1 else 0, first)


def seen(item, shift):
    """A histogram in the live view: a numbered frame, summed, its photons counted."""
    photons = int(item.counts.sum())
    return Seen(item.frame, item.complete, item.image, photons, True)


def tally(totals, item):
    """A saved histogram's photons."""
    totals.events += int(item.counts.sum())


KIND = DataKind(
    name="histogram", rank=0, readout=AcquisitionMode.HISTOGRAM, packet="histogram",
    assembler=HistogramAssembler, item=HistogramFrame, rows="histograms", format_version=2,
    what="histograms", counted=True, imager=False, per_pixel="image",
    create=create, fits=fits, append=append, blank=blank, read=read, tally=tally, replay=replay,
    seen=seen, exports=("ptu",))
