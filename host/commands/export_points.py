"""``fliss export DEPTH --to ply|pcd|las|mcap|mcap-ros2 -o OUT``: a depth capture's frames as a
point cloud (docs/point-clouds.md), read and written a run of frames at a time."""

import os
import sys
import time

import h5py

from ..errors import UserError
from ..kinds import article, for_mode
from ..pointcloud.export import WRITERS, export_points
from ..pointcloud.options import FLAGS, geometry_of


__all__ = ["POINT_FORMATS", "run_points", "refuse_geometry_flags"]

#: The point cloud formats, by ``--to`` name: their description.
POINT_FORMATS = {"ply": "PLY point cloud", "pcd": "PCD point cloud", "las": "LAS point cloud",
                 "mcap": "MCAP of Foxglove point clouds",
                 "mcap-ros2": "MCAP of ROS 2 PointCloud2 messages"}
assert set(POINT_FORMATS) == set(WRITERS)


def refuse_geometry_flags(args):
    """Refuse a geometry flag given to an export that makes no points."""
    for name, flag in FLAGS.items():
        if getattr(args, name, None) is not None:
            raise UserError(f"{flag}: the sensor's geometry places a depth capture's points: it "
                            f"is for --to {', '.join(POINT_FORMATS)}, not --to {args.to}")


def _mode_and_geometry(path):
    # The capture's mode and recorded geometry, or a refusal of a file that holds no depth frames
    try:
        if not h5py.is_hdf5(path):
            raise UserError(f"{path}: not a FLISS capture file: a point cloud is made of a depth "
                            f"capture's frames (fliss capture --readout depth)")
        with h5py.File(path, "r") as f:
            mode = f.attrs.get("mode")
            geometry = f.attrs.get("geometry")
    except OSError as error:
        raise UserError(f"cannot read {path}: {error.strerror or error}") from None
    mode = mode.decode() if isinstance(mode, bytes) else mode
    geometry = geometry.decode() if isinstance(geometry, bytes) else geometry
    return mode, (None if geometry is None else str(geometry))


def run_points(args):
    """``fliss export`` to a point cloud format; ``args`` as the export command parsed them,
    its output already checked."""
    path = args.capture
    mode, recorded = _mode_and_geometry(path)
    kind = for_mode(mode)
    if args.to not in kind.exports:
        what = f"{article(mode)} capture" if isinstance(mode, str) else "a capture of no kind"
        raise UserError(f"{path}: {what} has no depth frames: a point cloud (--to {args.to}) is "
                        f"made of a depth capture's frames (fliss capture --readout depth)")
    geometry, note = geometry_of(args, recorded, source=path)
    quiet = getattr(args, "quiet", 0) > 0
    if note is not None:
        print(f"fliss: warning: {note}", file=sys.stderr)
    folder, base = os.path.split(os.path.abspath(args.output))
    partial = os.path.join(folder, f".{base}.{os.getpid()}.part")
    start = time.perf_counter()
    try:
        written = export_points(path, partial, args.to, geometry,
                                comments=[f"FLISS depth capture {os.path.basename(path)}",
                                          "frame: optical, x right, y down, z forward, metres"])
        os.replace(partial, args.output)
    except ValueError as error:
        raise UserError(str(error)) from None
    except (OSError, KeyError) as error:
        reason = getattr(error, "strerror", None) or error
        raise UserError(f"cannot export {path} to {args.output}: {reason}") from None
    finally:
        if os.path.exists(partial):
            os.unlink(partial)
    if written.incomplete:
        print(f"fliss: warning: {path}: {written.incomplete} frame"
              f"{'s' if written.incomplete != 1 else ''} not whole in the capture (never "
              f"arrived, or not finished on disk): no points of them", file=sys.stderr)
    if not quiet:
        print(f"wrote {args.output}: {POINT_FORMATS[args.to]}, {written.points} points of "
              f"{written.frames} frames, {os.path.getsize(args.output)} bytes, "
              f"{time.perf_counter() - start:.2f} s")
    return 0
