"""Depth frames as points: one point per detected pixel per frame.

A point carries its place (``x``, ``y``, ``z``, metres, in the sensor's optical frame:
:mod:`.geometry`), its ``range`` along the pixel's ray (the depth frame's ``depth_m``), the
peak's ``height`` and the ``background`` under it (counts, as the depth engine measured them),
the ``frame`` number, the sensor's ``pixel`` address and the frame's host ``time`` (seconds).
"""

import numpy as np


__all__ = ["POINT_DTYPE", "frame_points"]


#: One point, as every export writes it (little-endian, packed).
POINT_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("range", "<f4"),
                        ("height", "<f4"), ("background", "<f4"), ("frame", "<u4"),
                        ("pixel", "<u2"), ("time", "<f8")])


def frame_points(geometry, pixels, depth_m, detected, height, background, frames, times):
    """The points of a run of depth frames: ``depth_m``, ``detected``, ``height`` and
    ``background`` of shape ``(frames, pixels)``, ``pixels`` the sensor addresses of the
    columns, ``frames`` and ``times`` one per row. Frame after frame, pixel after pixel; a
    pixel that is not detected (or whose depth is not a finite number) gives no point."""
    depth_m = np.asarray(depth_m)
    width = depth_m.shape[1] if depth_m.ndim == 2 else 1
    keep = np.asarray(detected, dtype=bool) & np.isfinite(depth_m)
    # Where the points are, as flat indices (frame * width + pixel): one integer a point
    flat = np.flatnonzero(keep)
    del keep
    count = len(flat)
    points = np.empty(count, dtype=POINT_DTYPE)
    ranges = depth_m.reshape(-1)[flat].astype(float, copy=False)
    points["range"] = ranges
    columns = flat % width
    rays = geometry.rays(pixels)
    # One coordinate at a time, through one scratch array: a float a point
    scratch = np.empty(count)
    for axis, name in enumerate("xyz"):
        np.take(rays[:, axis], columns, out=scratch)
        scratch *= ranges
        points[name] = scratch
    del ranges, scratch
    points["pixel"] = np.asarray(pixels)[columns]
    del columns
    points["height"] = np.asarray(height).reshape(-1)[flat]
    points["background"] = np.asarray(background).reshape(-1)[flat]
    rows = np.floor_divide(flat, width, out=flat)
    points["frame"] = np.asarray(frames)[rows]
    points["time"] = np.asarray(times, dtype=float)[rows]
    return points
