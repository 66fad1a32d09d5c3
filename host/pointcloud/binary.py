"""A file of a text header then the points as packed records: what PLY and PCD have in common."""

from .points import POINT_DTYPE


__all__ = ["PackedWriter"]


class PackedWriter:
    """Writes ``total`` points to ``path`` after the header's lines (:meth:`header`, given
    ``total`` and ``comments``): :meth:`write` each run, then :meth:`close`."""

    #: The format's name, for messages.
    name = ""

    def __init__(self, path, total, comments=()):
        self.total, self.written = total, 0
        lines = self.header(total, [" ".join(str(line).split()) for line in comments])
        self._file = open(path, "wb")
        self._file.write(("\n".join(lines) + "\n").encode("ascii", "replace"))

    def header(self, total, comments):
        raise NotImplementedError

    def write(self, points, frame_times=None):
        # Straight from the array: no copy of the run as bytes
        points.astype(POINT_DTYPE, copy=False).tofile(self._file)
        self.written += len(points)

    def close(self, check=True):
        """Finish the file; ``check``: refuse a count of points other than the one announced."""
        self._file.close()
        if check and self.written != self.total:
            raise RuntimeError(f"{self.name} header says {self.total} points, {self.written} "
                               f"written")
