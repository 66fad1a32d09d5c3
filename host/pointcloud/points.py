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
    depth_m = np.asarray(depth_m, dtype=float)
    keep = np.asarray(detected, dtype=bool) & np.isfinite(depth_m)
    rows, columns = np.nonzero(keep)
    rays = geometry.rays(pixels)
    ranges = depth_m[rows, columns]
    points = np.zeros(len(rows), dtype=POINT_DTYPE)
    place = rays[columns] * ranges[:, None]
    points["x"], points["y"], points["z"] = place[:, 0], place[:, 1], place[:, 2]
    points["range"] = ranges
    points["height"] = np.asarray(height, dtype=float)[rows, columns]
    points["background"] = np.asarray(background, dtype=float)[rows, columns]
    points["frame"] = np.asarray(frames)[rows]
    points["pixel"] = np.asarray(pixels)[columns]
    points["time"] = np.asarray(times, dtype=float)[rows]
    return points
