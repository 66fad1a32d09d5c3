"""A depth capture's frames as a point cloud file, run by run: memory bounded by a run of
frames, not by the capture."""

from dataclasses import dataclass

import h5py
import numpy as np

from .las import LasWriter
from .mcap_file import McapWriter
from .pcd import PcdWriter
from .ply import PlyWriter
from .points import POINT_DTYPE, frame_points
from .ros2 import Ros2Writer


__all__ = ["WRITERS", "PointsExport", "export_points", "RUN_FRAMES"]

#: The formats, by the name ``fliss export --to`` takes.
WRITERS = {"ply": PlyWriter, "pcd": PcdWriter, "las": LasWriter, "mcap": McapWriter,
           "mcap-ros2": Ros2Writer}

#: The group of a capture file that holds its depth frames (:mod:`fliss.host.kinds.depth`).
_GROUP = "depth"

#: Frames read, turned into points and written at a time.
RUN_FRAMES = 4096

#: HDF5's metadata cache while a capture is read, in the bytes it counts (the entries' size on
#: disk). A chunked dataset's chunk index (a B-tree) costs about eight times its counted size in
#: memory, and HDF5 keeps every node a read passes through until the cache is full (at first 2
#: MB counted, some 16 MB resident, and more as it grows): read front to back, run after run,
#: that was memory growing with the capture, not the run. A small fixed cache still holds the
#: path down each dataset's index.
_METADATA_CACHE = 128 * 1024


@dataclass
class PointsExport:
    """What :func:`export_points` wrote: ``points``, of ``frames`` frames, and the frames it
    left out because the capture does not hold them whole (``incomplete``: a frame that never
    arrived, or a row its writer never finished)."""
    points: int
    frames: int
    incomplete: int


def _rows(group, name, start, stop):
    return group[name][start:stop]


def _run(group, start, stop, pick):
    # The run's arrays by name, each read when asked for (frame_points lets each go once used)
    return lambda name: _rows(group, name, start, stop)[pick]


def _open(path):
    """``path`` opened to read run by run: no cache of raw chunks (every chunk is read once)
    and a metadata cache of fixed size (:data:`_METADATA_CACHE`, never grown)."""
    f = h5py.File(path, "r", rdcc_nbytes=0)
    try:
        config = f.id.get_mdc_config()
        config.set_initial_size = True
        config.initial_size = config.max_size = _METADATA_CACHE
        config.min_size = min(config.min_size, _METADATA_CACHE)
        config.incr_mode = config.flash_incr_mode = config.decr_mode = 0
        f.id.set_mdc_config(config)
    except BaseException:
        f.close()
        raise
    return f


def export_points(capture_path, output, to, geometry, *, comments=(), run_frames=RUN_FRAMES):
    """Write the points of the depth capture ``capture_path`` (its ``/depth`` group) to
    ``output`` in the format ``to`` (:data:`WRITERS`), placed by ``geometry`` (a
    :class:`~.geometry.SensorGeometry`). Raises :exc:`ValueError` for a file that is not a
    depth capture, :exc:`OSError` for one that cannot be read or written."""
    writer_type = WRITERS[to]
    with _open(capture_path) as f:
        group = f.get(_GROUP)
        if not isinstance(group, h5py.Group):
            raise ValueError(f"{capture_path} is not a depth capture (fliss capture "
                             f"--readout depth): it has no depth frames to make points of")
        rows = min(len(group[name]) for name in ("complete", "detected", "depth_m",
                                                 "height", "background", "frame", "time_s"))
        pixels = group["pixel"][()]
        total = 0
        for start in range(0, rows, run_frames):
            stop = min(rows, start + run_frames)
            keep = _rows(group, "complete", start, stop)
            detected = _rows(group, "detected", start, stop) & keep[:, None]
            finite = np.isfinite(_rows(group, "depth_m", start, stop))
            total += int((detected & finite).sum())
        writer = writer_type(output, total, comments)
        frames = incomplete = 0
        finished = False
        # Every run's points in one array, made once: a run's points never fill a new block of
        # memory, which the memory each run frees between (a message, a chunk) would leave
        # fragmented (its pages resident only as far as the most points of a run)
        buffer = np.empty(run_frames * len(pixels), dtype=POINT_DTYPE)
        try:
            for start in range(0, rows, run_frames):
                stop = min(rows, start + run_frames)
                keep = _rows(group, "complete", start, stop).astype(bool)
                # Every frame of a run whole (the usual case): its arrays as read, no copies
                pick = slice(None) if keep.all() else keep
                numbers = _rows(group, "frame", start, stop)[pick]
                times = _rows(group, "time_s", start, stop)[pick]
                points = frame_points(geometry, pixels, _run(group, start, stop, pick),
                                      numbers, times, out=buffer)
                writer.write(points, dict(zip(numbers.tolist(), times.tolist())))
                frames += int(keep.sum())
                incomplete += int((~keep).sum())
            finished = True
        finally:
            writer.close(check=finished)
    return PointsExport(total, frames, incomplete)
