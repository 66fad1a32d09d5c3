"""Points to PCD (the Point Cloud Library's format, version 0.7, binary): an unorganised cloud
of every field of :data:`~.points.POINT_DTYPE`, written run by run."""

from .binary import PackedWriter
from .points import POINT_DTYPE


__all__ = ["PcdWriter"]

_TYPES = {"f": "F", "u": "U", "i": "I"}


class PcdWriter(PackedWriter):
    """Writes ``total`` points to ``path``: :meth:`write` each run, then :meth:`close`.
    ``comments`` are ``#`` lines at the top of the header."""

    name = "PCD"
    suffix = ".pcd"

    def header(self, total, comments):
        fields = [POINT_DTYPE.fields[name][0] for name in POINT_DTYPE.names]
        return [*(f"# {line}" for line in comments),
                "VERSION 0.7",
                "FIELDS " + " ".join(POINT_DTYPE.names),
                "SIZE " + " ".join(str(dtype.itemsize) for dtype in fields),
                "TYPE " + " ".join(_TYPES[dtype.kind] for dtype in fields),
                "COUNT " + " ".join("1" for _ in fields),
                f"WIDTH {total}", "HEIGHT 1", "VIEWPOINT 0 0 0 1 0 0 0",
                f"POINTS {total}", "DATA binary"]
