"""Room for a capture file to grow: refused before HDF5 writes, not after.

HDF5 that meets a full disk or the process's file-size limit (``ulimit -f``) mid-write goes on
writing into its cache, reports the failures where no caller sees them (when a dataset's handle
is freed), and leaves a file whose superblock names an end past the real one: no one can open
it, and the writer may crash. :class:`Room` checks before each append that the file can still
grow by what comes; refused there (:exc:`~fliss.host.errors.FileFull`), the file closes whole
with everything written before.
"""

import errno
import os
import resource

import h5py
import numpy as np

from .errors import FileFull


__all__ = ["Room"]

#: Bytes kept for the end's attributes and counters, written when the file is closed.
END_BYTES = 64 << 10


class Room:
    """Room for the HDF5 file ``file`` (an open :class:`h5py.File`) at ``path`` to grow.

    The room needed for an append is the bytes appended since the last flush (twice: HDF5 may
    write a compressed chunk again elsewhere), a new chunk of every dataset (allocated whole
    when its first row is flushed), and :data:`END_BYTES`."""

    def __init__(self, file, path):
        self.file = file
        self.folder = os.path.dirname(os.path.abspath(path))
        chunks = []
        file.visititems(lambda name, item: chunks.append(
            int(np.prod(item.chunks)) * item.dtype.itemsize
            if isinstance(item, h5py.Dataset) and item.chunks else 0))
        self.reserve = sum(chunks) + END_BYTES
        self.pending = 0

    def flushed(self):
        """Everything appended so far is on the disk."""
        self.pending = 0

    def check(self, nbytes):
        """Raise :exc:`~fliss.host.errors.FileFull` unless the file can grow by ``nbytes``
        more: under the process's file-size limit and on its disk."""
        self.pending += nbytes
        grows = 2 * self.pending + self.reserve
        limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
        if limit != resource.RLIM_INFINITY and self.file.id.get_filesize() + grows > limit:
            raise FileFull(errno.EFBIG, f"the file size limit is reached (ulimit -f: {limit} "
                                        f"bytes)")
        disk = os.statvfs(self.folder)
        free = disk.f_bavail * disk.f_frsize
        if grows > free:
            raise FileFull(errno.ENOSPC, f"the disk is full ({free} bytes free)")
