"""Points to PCD (the Point Cloud Library's format, version 0.7, binary): an unorganised cloud
of every field of :data:`~.points.POINT_DTYPE`, written run by run."""

from .points import POINT_DTYPE


__all__ = ["PcdWriter"]

_TYPES = {"f": "F", "u": "U", "i": "I"}


class PcdWriter:
    """Writes ``total`` points to ``path``: :meth:`write` each run, then :meth:`close`.
    ``comments`` are ``#`` lines at the top of the header."""

    suffix = ".pcd"

    def __init__(self, path, total, comments=()):
        self.total, self.written = total, 0
        fields = [POINT_DTYPE.fields[name][0] for name in POINT_DTYPE.names]
        header = [f"# {line}" for line in comments]
        header += ["VERSION 0.7",
                   "FIELDS " + " ".join(POINT_DTYPE.names),
                   "SIZE " + " ".join(str(dtype.itemsize) for dtype in fields),
                   "TYPE " + " ".join(_TYPES[dtype.kind] for dtype in fields),
                   "COUNT " + " ".join("1" for _ in fields),
                   f"WIDTH {total}", "HEIGHT 1", "VIEWPOINT 0 0 0 1 0 0 0",
                   f"POINTS {total}", "DATA binary"]
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
            raise RuntimeError(f"PCD header says {self.total} points, {self.written} written")
