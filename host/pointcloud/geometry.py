"""Where each pixel of the sensor looks: the geometry that turns a depth frame into points.

A pixel at address ``a`` sits at row ``a // columns``, column ``a % columns`` of the array
(``columns`` 1: the paper's sensor, one column; a grid ``columns`` wide), or at the position a
per-pixel table gives. Through a pinhole lens of focal length ``focal_m`` it looks along the ray
from the lens through its centre: ``((column - cx) * pitch, (row - cy) * pitch, focal)``, with
``(cx, cy)`` the optical centre in pixels (by default the middle of the array). A depth is the
distance along that ray (the time of flight's path, halved), so a point is the depth times the
ray's unit vector.

The frame is the camera's optical frame: ``x`` to the right of the image, ``y`` down it, ``z``
forward along the optical axis (ROS REP 103's ``_optical_frame``), in metres.
"""

import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np


__all__ = ["SensorGeometry", "PAPER_SENSOR"]


@dataclass(frozen=True)
class SensorGeometry:
    """The sensor's pixel layout and its lens.

    Parameters
    ----------
    columns : int
        Pixels per row: 1 for a column, ``W`` for a grid ``W`` wide.
    pitch_m : float
        Pixel pitch (square pixels), in metres.
    focal_m : float
        The lens's focal length, in metres.
    centre : (float, float) or None
        The optical centre ``(cx, cy)``, in pixels (column, row); None: the middle of the
        pixels the frame has.
    positions : tuple of (float, float) or None
        A position ``(column, row)`` in pixels for each pixel address, instead of the layout
        ``columns`` gives (a sensor whose pixels are not on a grid).
    """
    columns: int = 1
    pitch_m: float = 30e-6
    focal_m: float = 2.5e-3
    centre: Optional[Tuple[float, float]] = None
    positions: Optional[Tuple[Tuple[float, float], ...]] = None

    def __post_init__(self):
        if isinstance(self.columns, bool) or not isinstance(self.columns, int) \
                or self.columns < 1:
            raise ValueError(f"the pixels per row must be a positive whole number, not "
                             f"{self.columns!r}")
        for name in ("pitch_m", "focal_m"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a positive length, not {value!r}")
        if self.centre is not None and (len(self.centre) != 2 or not all(
                math.isfinite(float(c)) for c in self.centre)):
            raise ValueError(f"the optical centre must be two finite numbers (column, row), "
                             f"not {self.centre!r}")

    @classmethod
    def from_fov(cls, fov_rad, pixels, **options):
        """The geometry whose ``pixels`` pixels along the array's long side (a column's
        length, a grid's width) span the field of view ``fov_rad`` (edge to edge)."""
        if not 0 < fov_rad < math.pi:
            raise ValueError(f"the field of view must be between 0 and 180 degrees, not "
                             f"{math.degrees(fov_rad):g} degrees")
        pitch = options.get("pitch_m", cls.pitch_m)
        focal = pixels * pitch / 2 / math.tan(fov_rad / 2)
        return cls(focal_m=focal, **options)

    def field_of_view(self, pixels):
        """The field of view, in radians, of ``pixels`` pixels side by side (edge to edge)."""
        return 2 * math.atan(pixels * self.pitch_m / 2 / self.focal_m)

    def places(self, addresses):
        """``(column, row)`` in pixels of each address of ``addresses``."""
        addresses = np.asarray(addresses, dtype=np.int64)
        if self.positions is not None:
            if addresses.size and (addresses.min() < 0 or addresses.max() >= len(self.positions)):
                raise ValueError(f"the geometry places {len(self.positions)} pixels; the "
                                 f"frame has addresses up to {int(addresses.max())}")
            table = np.asarray(self.positions, dtype=float)
            return table[addresses, 0], table[addresses, 1]
        return (addresses % self.columns).astype(float), (addresses // self.columns).astype(float)

    def image_shape(self, addresses):
        """``(rows, columns)`` of the image that the pixels of ``addresses`` fill, row by row, in
        their order: for a grid (``columns`` above 1, no ``positions``) whose addresses run on,
        one by one, from the start of a row to the end of one; else None (a column, pixels
        placed by a table, or part rows: shown as a profile)."""
        addresses = np.asarray(addresses, dtype=np.int64)
        if self.positions is not None or self.columns < 2 or addresses.size < self.columns:
            return None
        if addresses[0] % self.columns or addresses.size % self.columns \
                or np.any(np.diff(addresses) != 1):
            return None
        return addresses.size // self.columns, self.columns

    def rays(self, addresses):
        """The unit vector each pixel of ``addresses`` looks along, shape ``(len, 3)``; the
        optical centre, when not given, is the middle of these pixels."""
        column, row = self.places(addresses)
        if self.centre is not None:
            cx, cy = (float(c) for c in self.centre)
        elif column.size:
            cx, cy = (column.min() + column.max()) / 2, (row.min() + row.max()) / 2
        else:
            cx = cy = 0.0
        ray = np.stack([(column - cx) * self.pitch_m, (row - cy) * self.pitch_m,
                        np.full(column.shape, self.focal_m)], axis=-1)
        return ray / np.linalg.norm(ray, axis=-1, keepdims=True)

    def describe(self):
        """The geometry as plain values (for a file's metadata)."""
        return {"columns": self.columns, "pitch_m": self.pitch_m, "focal_m": self.focal_m,
                "centre": None if self.centre is None else [float(c) for c in self.centre],
                "positions": None if self.positions is None else
                [[float(c), float(r)] for c, r in self.positions],
                "frame": "optical: x right, y down, z forward (metres)"}


#: The paper's sensor (section 4, Table 1): one column of 30 µm pixels. The paper gives no lens:
#: the 2.5 mm focal length is FLISS's choice (a 39.6 degree field of view over 60 pixels), and
#: files made with it say so.
PAPER_SENSOR = SensorGeometry()
