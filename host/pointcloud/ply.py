"""Points to PLY (binary, little-endian): one ``vertex`` element with every field of
:data:`~.points.POINT_DTYPE` as a property, written run by run."""

from .binary import PackedWriter
from .points import POINT_DTYPE


__all__ = ["PlyWriter"]

_TYPES = {"<f4": "float", "<f8": "double", "<u4": "uint", "<u2": "ushort"}


class PlyWriter(PackedWriter):
    """Writes ``total`` points to ``path``: :meth:`write` each run, then :meth:`close`.
    ``comments`` are lines for the header (the capture, the geometry)."""

    name = "PLY"
    suffix = ".ply"

    def header(self, total, comments):
        return ["ply", "format binary_little_endian 1.0",
                *(f"comment {line}" for line in comments),
                f"element vertex {total}",
                *(f"property {_TYPES[POINT_DTYPE.fields[name][0].str]} {name}"
                  for name in POINT_DTYPE.names),
                "end_header"]
