"""A depth capture's frames as a point cloud file, run by run: memory bounded by a run of
frames, not by the capture."""

from dataclasses import dataclass

import h5py
import numpy as np

from .las import LasWriter
from .mcap_file import McapWriter
from .pcd import PcdWriter
from .ply import PlyWriter
from .points import frame_points


__all__ = ["WRITERS", "PointsExport", "export_points", "RUN_FRAMES"]

#: The formats, by the name ``fliss export --to`` takes.
WRITERS = {"ply": PlyWriter, "pcd": PcdWriter, "las": LasWriter, "mcap": McapWriter}

#: The group of a capture file that holds its depth frames (:mod:`fliss.host.kinds.depth`).
_GROUP = "depth"

#: Frames read, turned into points and written at a time.
RUN_FRAMES = 4096


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


def export_points(capture_path, output, to, geometry, *, comments=(), run_frames=RUN_FRAMES):
    """Write the points of the depth capture ``capture_path`` (its ``/depth`` group) to
    ``output`` in the format ``to`` (:data:`WRITERS`), placed by ``geometry`` (a
    :class:`~.geometry.SensorGeometry`). Raises :exc:`ValueError` for a file that is not a
    depth capture, :exc:`OSError` for one that cannot be read or written."""
    writer_type = WRITERS[to]
    with h5py.File(capture_path, "r", rdcc_nbytes=0) as f:
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
        try:
            for start in range(0, rows, run_frames):
                stop = min(rows, start + run_frames)
                keep = _rows(group, "complete", start, stop).astype(bool)
                # Every frame of a run whole (the usual case): its arrays as read, no copies
                pick = slice(None) if keep.all() else keep
                numbers = _rows(group, "frame", start, stop)[pick]
                times = _rows(group, "time_s", start, stop)[pick]
                points = frame_points(
                    geometry, pixels, _rows(group, "depth_m", start, stop)[pick],
                    _rows(group, "detected", start, stop)[pick],
                    _rows(group, "height", start, stop)[pick],
                    _rows(group, "background", start, stop)[pick], numbers, times)
                writer.write(points, dict(zip(numbers.tolist(), times.tolist())))
                del points          # (before the next run is read: one run's points at a time)
                frames += int(keep.sum())
                incomplete += int((~keep).sum())
            finished = True
        finally:
            writer.close(check=finished)
    return PointsExport(total, frames, incomplete)
