"""Points to LAS 1.4 (ASPRS), through laspy, written run by run.

Point format 6: ``x``, ``y``, ``z`` to 0.1 mm, ``intensity`` the peak's height (counts,
rounded, at most 65535), ``gps_time`` the frame's host time (seconds), ``point_source_id``
the pixel's address; and as extra bytes (the LAS 1.4 "extra bytes" record, which laspy, PDAL
and CloudCompare read) every field of :data:`~.points.POINT_DTYPE` the standard fields do not
hold exactly: ``range``, ``height``, ``background`` and ``frame``.
"""

import numpy as np

from .points import POINT_DTYPE


__all__ = ["LasWriter", "SCALE_M"]

#: The coordinates' step: 0.1 mm.
SCALE_M = 1e-4
_EXTRA = ("range", "height", "background", "frame")
#: Points handed to laspy at a time.
_SLICE = 1 << 16


class LasWriter:
    """Writes ``total`` points to ``path``: :meth:`write` each run, then :meth:`close`.
    ``comments`` go to the header's generating software field (the first, cut to 32
    characters) only: LAS has no place for free text that every reader shows."""

    suffix = ".las"

    def __init__(self, path, total, comments=()):
        import laspy

        self.total, self.written = total, 0
        header = laspy.LasHeader(point_format=6, version="1.4")
        header.scales = np.full(3, SCALE_M)
        header.offsets = np.zeros(3)
        header.generating_software = "FLISS"
        header.add_extra_dims([laspy.ExtraBytesParams(name, POINT_DTYPE.fields[name][0],
                                                      description=name)
                               for name in _EXTRA])
        self._header = header
        self._record_type = laspy.ScaleAwarePointRecord
        self._writer = laspy.open(path, mode="w", header=header)

    def write(self, points, frame_times=None):
        # In slices: laspy's record of a slice, not of the whole run, beside the run's points
        for start in range(0, len(points), _SLICE):
            self._write(points[start:start + _SLICE])

    def _write(self, points):
        record = self._record_type.zeros(len(points), header=self._header)
        record.x, record.y, record.z = points["x"], points["y"], points["z"]
        record.intensity = np.clip(np.rint(points["height"]), 0, 65535).astype(np.uint16)
        record.gps_time = points["time"]
        record.point_source_id = points["pixel"]
        for name in _EXTRA:
            record[name] = points[name]
        self._writer.write_points(record)
        self.written += len(points)

    def close(self, check=True):
        """Finish the file; ``check``: refuse a count of points other than the one announced."""
        self._writer.close()
        if check and self.written != self.total:
            raise RuntimeError(f"{self.total} points expected, {self.written} written")
