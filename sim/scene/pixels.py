"""The pixel array of the scene simulator: a depth map, and the two sensor kinds.

A :class:`PixelArray` given as :attr:`Scene.pixels <fliss.sim.scene.description.Scene.pixels>`
turns the single-pixel scene into an imager: every pixel looks at its own point of the scene,
at its own distance and with its own reflectivity, and they share the background and the
aggressors (a flash aggressor lights every pixel). :class:`~fliss.sim.scene.array.PixelSimulation`
simulates it.

Photons per pixel
-----------------
* Echo: pixel ``i`` detects on average ``detections_per_pulse * reflectivity[i] *
  (REFERENCE_DISTANCE_M / distance_m[i])**2`` photons per victim pulse (the scene's
  ``detections_per_pulse`` is what a pixel sees of a target of reflectivity 1 at 4 m; a
  Lambertian target fills the pixel, so the echo falls as ``1 / z**2``), ``2 z_i / c`` after the
  pulse.
* Background: every pixel gets its own Poisson process of the scene's ``background_hz``.
* Aggressors: every pixel gets the aggressor's ``detections_per_pulse`` per aggressor pulse
  (flash illumination of the whole field of view), after the aggressor's offset plus the time
  of flight: the pixel's own round trip when the aggressor's ``tof_s`` is ``None`` (aggressor
  beside the victim, its light scattered by the point the pixel images), else ``tof_s``.
* Each pixel's SPAD has its own non-paralysable dead time.

Sensor kinds
------------
``"column"``
    The paper's sensor (section 4, Figure 6): the pixels share one output line to one TDC bank.
    The TDC keeps the *last* detection of the laser cycle, from whichever pixel (the last pixel
    to fire wins, with the scene's ``keep = "last"``; ``"first"`` keeps the first), and reports
    that pixel's address. **Collision rule** (the paper names the flag, not its rule; this is the
    model's): the event's collision flag is set when another pixel fired within
    :data:`COLLISION_WINDOW_S` before the winning detection in the same TDC window (after it,
    with ``keep = "first"``): both pulses were on the shared line at once. The window is one
    period of the TDC's 625 MHz time base (1.6 ns, 32 codes), the line's resolution. At most
    one event per laser cycle.
``"per_pixel"``
    One TDC per pixel: each pixel keeps its own last (or first) detection of the laser cycle;
    up to one event per pixel and cycle, never a collision. The events of a cycle come in
    address order (as a readout scans the pixels).
"""

from dataclasses import dataclass

import numpy as np

from ...hdl.event import ADDRESS_BITS
from .checks import check_number


__all__ = ["SENSOR_KINDS", "COLLISION_WINDOW_S", "REFERENCE_DISTANCE_M", "LINE_PIXELS",
           "SCENE_NAMES", "PixelArray", "line_pixels", "pixels_named"]


#: The sensor kinds a :class:`PixelArray` can have.
SENSOR_KINDS = ("column", "per_pixel")

#: Collision window of the column sensor: one period of its 625 MHz TDC time base, in seconds.
COLLISION_WINDOW_S = 1.6e-9

#: Distance at which a target of reflectivity 1 gives a pixel the scene's
#: ``detections_per_pulse``, in metres (the paper's wall).
REFERENCE_DISTANCE_M = 4.0

#: Pixels of the paper's column (Table 1: 60 x 1).
LINE_PIXELS = 60


def _as_vector(values, count, what):
    array = np.asarray(values, dtype=np.float64)
    if array.ndim == 0:
        array = np.full(count, float(array))
    if array.ndim != 1 or len(array) != count:
        raise ValueError(f"{what} must be one number or one per pixel ({count}), "
                         f"not {np.shape(values)}")
    if not np.all(np.isfinite(array)) or np.any(array < 0):
        raise ValueError(f"{what} must be finite and non-negative for every pixel")
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class PixelArray:
    """Pixels, each looking at its own point of the scene (a depth map), and the sensor kind.

    Parameters
    ----------
    distance_m : array_like
        Target distance of each pixel, metres (positive); its length is the number of pixels,
        1 to 64.
    reflectivity : float or array_like
        Reflectivity of each pixel's target (one number: all the same), 0 or more.
    sensor : str
        ``"column"`` (one TDC bank for all, the last pixel to fire wins, collision flag) or
        ``"per_pixel"`` (one TDC per pixel); see :mod:`fliss.sim.scene.pixels`.
    first_address : int
        Address of the first pixel; pixel ``i`` has address ``first_address + i`` (below 64).
    collision_window_s : float
        Collision window of the column sensor, seconds.
    columns : int
        Layout of the pixels, for the detector's crosstalk: pixel ``i`` sits in row ``i //
        columns`` and column ``i % columns`` of a grid ``columns`` wide (1, the default: a
        column, each pixel's neighbours the pixels above and below).
    """

    distance_m: object
    reflectivity: object = 0.8
    sensor: str = "column"
    first_address: int = 0
    collision_window_s: float = COLLISION_WINDOW_S
    columns: int = 1

    def __post_init__(self):
        distance = np.asarray(self.distance_m, dtype=np.float64)
        if distance.ndim != 1 or not 1 <= len(distance) <= (1 << ADDRESS_BITS):
            raise ValueError(f"A pixel array has 1 to {1 << ADDRESS_BITS} pixels: give one "
                             f"distance per pixel, not an array of shape {distance.shape}")
        distance = _as_vector(distance, len(distance), "Pixel target distance (m)")
        if np.any(distance <= 0):
            raise ValueError("Pixel target distances must be positive (metres)")
        object.__setattr__(self, "distance_m", distance)
        object.__setattr__(self, "reflectivity",
                           _as_vector(self.reflectivity, len(distance), "Pixel reflectivity"))
        if self.sensor not in SENSOR_KINDS:
            raise ValueError(f"Sensor kind must be one of {', '.join(SENSOR_KINDS)}, "
                             f"not {self.sensor!r}")
        if isinstance(self.first_address, bool) or \
                not isinstance(self.first_address, (int, np.integer)) or \
                not 0 <= self.first_address <= (1 << ADDRESS_BITS) - len(distance):
            raise ValueError(f"First pixel address must be an integer from 0 to "
                             f"{(1 << ADDRESS_BITS) - len(distance)} for {len(distance)} "
                             f"pixels, not {self.first_address!r}")
        check_number(self.collision_window_s, "Collision window (s)")
        if isinstance(self.columns, bool) or not isinstance(self.columns, (int, np.integer)) \
                or self.columns < 1 or len(distance) % self.columns:
            raise ValueError(f"The pixels' columns must be a positive integer that divides "
                             f"the {len(distance)} pixels, not {self.columns!r}")

    def __len__(self):
        return len(self.distance_m)

    @property
    def addresses(self):
        """Address of each pixel, ``numpy.int64``."""
        return self.first_address + np.arange(len(self), dtype=np.int64)

    def neighbours(self):
        """``(orthogonal, diagonal)``: for each pixel the indices of its 4 orthogonal and 4
        diagonal neighbours in the layout, ``-1`` where there is none (two ``(pixels, 4)``
        ``int64`` arrays)."""
        columns = int(self.columns)
        rows = len(self) // columns
        row, column = np.divmod(np.arange(len(self)), columns)
        tables = []
        for steps in (((-1, 0), (1, 0), (0, -1), (0, 1)),
                      ((-1, -1), (-1, 1), (1, -1), (1, 1))):
            table = np.full((len(self), 4), -1, dtype=np.int64)
            for at, (down, right) in enumerate(steps):
                r, c = row + down, column + right
                inside = (r >= 0) & (r < rows) & (c >= 0) & (c < columns)
                table[inside, at] = (r * columns + c)[inside]
            tables.append(table)
        return tuple(tables)

    def echo(self, detections_per_pulse):
        """Mean detected echo photons per victim pulse of each pixel, for a scene whose target
        of reflectivity 1 at :data:`REFERENCE_DISTANCE_M` gives ``detections_per_pulse``."""
        return detections_per_pulse * self.reflectivity * \
            (REFERENCE_DISTANCE_M / self.distance_m) ** 2

    def replace(self, **changes):
        """A copy with some fields changed."""
        from dataclasses import replace
        return replace(self, **changes)


def line_pixels(*, pixels=LINE_PIXELS, wall_m=4.0, object_m=2.5, object_pixels=(20, 40),
                wall_reflectivity=0.8, object_reflectivity=0.8, sensor="column",
                first_address=0):
    """The line scene: a column of ``pixels`` pixels looking at a wall ``wall_m`` away, with an
    object ``object_m`` away in front of pixels ``object_pixels[0] … object_pixels[1] - 1``.

    The defaults are the paper's column (60 pixels) and wall (4 m, reflectivity 0.8, Table 1),
    with an object at 2.5 m before the middle third.
    """
    if isinstance(pixels, bool) or not isinstance(pixels, (int, np.integer)) or pixels < 1:
        raise ValueError(f"A line has a positive whole number of pixels, not {pixels!r}")
    for value, what in ((wall_m, "Wall distance (m)"), (object_m, "Object distance (m)")):
        check_number(value, what, positive=True)
    low, high = object_pixels
    if not 0 <= low <= high <= pixels:
        raise ValueError(f"The object covers pixels from 0 to {pixels}, not {object_pixels!r}")
    distance = np.full(int(pixels), float(wall_m))
    reflectivity = np.full(int(pixels), float(wall_reflectivity))
    distance[low:high] = object_m
    reflectivity[low:high] = object_reflectivity
    return PixelArray(distance_m=distance, reflectivity=reflectivity, sensor=sensor,
                      first_address=first_address)



#: Scenes a board model can be started with by name (:func:`pixels_named`).
SCENE_NAMES = ("single", "line")


def pixels_named(name, *, sensor="column", wall_m=4.0, object_m=2.5):
    """The pixels of the scene called ``name``: ``None`` for ``"single"`` (one pixel, the
    single-pixel scene), :func:`line_pixels` with a wall ``wall_m`` and an object ``object_m``
    away for ``"line"``."""
    if name not in SCENE_NAMES:
        raise ValueError(f"Scene must be one of {', '.join(SCENE_NAMES)}, not {name!r}")
    if sensor not in SENSOR_KINDS:
        raise ValueError(f"Sensor kind must be one of {', '.join(SENSOR_KINDS)}, "
                         f"not {sensor!r}")
    if name == "single":
        return None
    return line_pixels(wall_m=wall_m, object_m=object_m, sensor=sensor)
