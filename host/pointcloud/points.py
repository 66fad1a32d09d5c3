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


#: Points placed at a time (:func:`_place`): its scratch arrays are a block's, not a run's.
_BLOCK = 1 << 16


def _place(points, rays, pixels, depths, flat, width):
    # x, y, z, range and pixel of the points at flat indices ``flat`` of the run's cells,
    # ``width`` a row, ``depths`` the run's depths by cell, ``rays`` the unit rays by column; a
    # block of points at a time, one coordinate at a time through one scratch array
    for start in range(0, len(flat), _BLOCK):
        block = points[start:start + _BLOCK]
        cells = flat[start:start + _BLOCK]
        ranges = depths[cells].astype(float, copy=False)
        block["range"] = ranges
        # (the index numpy's take works in, so that it makes no copy of it; and clipped,
        # never out of range, so that it writes straight to the scratch, not through a buffer)
        columns = np.remainder(cells, width, dtype=np.intp)
        block["pixel"] = pixels[columns]
        scratch = np.empty(len(cells))
        for axis, name in enumerate("xyz"):
            np.take(rays[:, axis], columns, out=scratch, mode="clip")
            scratch *= ranges
            block[name] = scratch


def frame_points(geometry, pixels, column, frames, times, out=None):
    """The points of a run of depth frames. ``column(name)`` gives the run's array ``name``,
    of shape ``(frames, pixels)``: ``depth_m``, ``detected``, ``height`` and ``background``,
    each asked for once, in that order, and let go as soon as it is used (a caller that reads
    them from a file never holds the four at once: at most ``depth_m`` and one other).
    ``pixels`` are the sensor addresses of the columns, ``frames`` and ``times`` one per row.
    Frame after frame, pixel after pixel; a pixel that is not detected (or whose depth is not
    a finite number) gives no point. ``out``: an array of :data:`POINT_DTYPE` to hold the
    points (its start; a new array when the points do not fit)."""
    depth_m = np.asarray(column("depth_m"))
    width = depth_m.shape[1] if depth_m.ndim == 2 else 1
    keep = np.isfinite(depth_m)
    keep &= np.asarray(column("detected"), dtype=bool)
    # Where the points are, as flat indices (frame * width + pixel): one integer a point, 32
    # bits while a run's cells fit (the search's own 64-bit answer briefly, before the points)
    flat = np.flatnonzero(keep)
    del keep
    if depth_m.size < 2**31:
        flat = flat.astype(np.int32)
    count = len(flat)
    points = (out[:count] if out is not None and len(out) >= count
              else np.empty(count, dtype=POINT_DTYPE))
    _place(points, geometry.rays(pixels), np.asarray(pixels), depth_m.reshape(-1), flat, width)
    del depth_m
    for name in ("height", "background"):
        points[name] = np.asarray(column(name)).reshape(-1)[flat]
    rows = np.floor_divide(flat, width, out=flat)
    points["frame"] = np.asarray(frames)[rows]
    points["time"] = np.asarray(times, dtype=float)[rows]
    return points
