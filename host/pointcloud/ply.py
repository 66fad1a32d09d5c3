"""Points to PLY (binary, little-endian): one ``vertex`` element with every field of
:data:`~.points.POINT_DTYPE` as a property, written run by run."""

from .points import POINT_DTYPE


__all__ = ["PlyWriter"]

_TYPES = {"<f4": "float", "<f8": "double", "<u4": "uint", "<u2": "ushort"}


class PlyWriter:
    """Writes ``total`` points to ``path``: :meth:`write` each run, then :meth:`close`.
    ``comments`` are lines for the header (the capture, the geometry)."""

    suffix = ".ply"

    def __init__(self, path, total, comments=()):
        self.total, self.written = total, 0
        header = ["ply", "format binary_little_endian 1.0"]
        header += [f"comment {line}" for line in comments]
        header.append(f"element vertex {total}")
        header += [f"property {_TYPES[POINT_DTYPE.fields[name][0].str]} {name}"
                   for name in POINT_DTYPE.names]
        header.append("end_header")
        self._file = open(path, "wb")
        self._file.write(("\n".join(header) + "\n").encode("ascii"))

    def write(self, points, frame_times=None):
        # Straight from the array: no copy of the run as bytes
        points.astype(POINT_DTYPE, copy=False).tofile(self._file)
        self.written += len(points)

    def close(self, check=True):
        """Finish the file; ``check``: refuse a count of points other than the one announced."""
        self._file.close()
        if check and self.written != self.total:
            raise RuntimeError(f"PLY header says {self.total} points, {self.written} written")
