"""What the imager's groups of a capture file share (``docs/file-format.md``): ``/image``
(per-pixel histograms, :mod:`fliss.host.kinds.image`) and ``/depth`` (depth frames,
:mod:`fliss.host.kinds.depth`), by frame and pixel: the rows of the frames, the pixel axis, how
a dataset names its axes, and how a group is read back.

Every dataset names its axes twice: HDF5 dimension scales (``pixel``: the sensor addresses,
``bin_time_s``: the time of each bin's centre, ``frame``: the board's frame numbers), which
h5py shows as ``dataset.dims``, and a plain ``axes`` attribute (``"frame,pixel,bin"``) for
readers that do not know dimension scales.
"""

import numpy as np



__all__ = ["ROW_DATASETS", "split_of", "rows_and_axes", "attach", "append_rows", "read_imager"]

#: Datasets of one row per frame (``complete`` False where never written).
ROW_DATASETS = (("frame", np.uint32), ("shift", np.uint8), ("time_s", np.float64),
                ("complete", np.bool_), ("missing_bins", np.uint32))

def split_of(configuration):
    """``(pixels, first pixel, bin shift)`` of a frame at the registers ``configuration``."""
    pixels = 1 << int(configuration.get("pixel_bits", 0))
    first = int(configuration.get("first_pixel", 0))
    shift = int(configuration.get("bin_shift", 0))
    return pixels, first, shift


def rows_and_axes(group, pixels, first):
    """The per-frame rows and the pixel axis of a new group; returns the frame and pixel
    scales."""
    for name, dtype in ROW_DATASETS:
        group.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(1024,))
    group["frame"].make_scale("frame")
    pixel = group.create_dataset("pixel", data=np.arange(first, first + pixels, dtype=np.uint8))
    pixel.attrs["unit"] = "address"
    pixel.make_scale("pixel")
    return group["frame"], pixel


def attach(dataset, scales, labels):
    """Name the axes of ``dataset`` ``labels``, with the dimension scales ``scales`` (None:
    none)."""
    for index, (scale, label) in enumerate(zip(scales, labels)):
        dataset.dims[index].label = label
        if scale is not None:
            dataset.dims[index].attach_scale(scale)
    dataset.attrs["axes"] = ",".join(labels)


def append_rows(group, index, items, completes, missing):
    """Rows ``index …`` of the frames' rows of ``group``, one an item of ``items``: its frame
    number, shift and time, its ``missing`` bins, and its ``completes`` last (False marks a
    row not on the disk)."""
    columns = {"frame": [item.frame for item in items], "shift": [item.shift for item in items],
               "time_s": [item.time_s for item in items], "missing_bins": missing,
               "complete": completes}
    for name in ("frame", "shift", "time_s", "missing_bins", "complete"):
        dataset = group[name]
        dataset.resize(index + len(items), axis=0)
        dataset[index:] = np.asarray(columns[name], dtype=dataset.dtype)


def read_imager(group, names, rows_of, problems):
    """The arrays of ``/image`` or ``/depth`` (``group``) by name: its datasets ``names`` and
    the rows', cut to the rows that every dataset holds, the pixel addresses, ``bin_time_s``
    where the group has it and ``bin_s``; ``rows_of(dataset, problems)`` reads a dataset's
    readable rows."""
    columns = {name: rows_of(group[name], problems) for name in names}
    for name, _ in ROW_DATASETS:
        if name in group:
            columns[name] = rows_of(group[name], problems)
        elif name != "missing_bins":
            raise ValueError(f"no {group.name}/{name}")
    rows = min(len(column) for column in columns.values())
    if any(len(column) > rows for column in columns.values()) and not problems:
        problems.append(f"frames after the first {rows} are incomplete on disk and left out")
    columns = {name: column[:rows] for name, column in columns.items()}
    columns["pixel"] = group["pixel"][()].astype(np.int64)
    if "bin_time_s" in group:
        columns["bin_time_s"] = group["bin_time_s"][()]
    columns["bin_s"] = float(group.attrs["bin_s"])
    return columns
