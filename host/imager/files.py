"""The imager's parts of a capture file (``docs/file-format.md``): ``/image`` (per-pixel
histograms, ``counts`` by frame, pixel and bin) and ``/depth`` (depth frames, by frame and
pixel), written by :class:`fliss.host.fileformat.CaptureWriter` and read by
:func:`fliss.host.fileformat.read_capture`.

Every dataset names its axes twice: HDF5 dimension scales (``pixel``: the sensor addresses,
``bin_time_s``: the time of each bin's centre, ``frame``: the board's frame numbers), which
h5py shows as ``dataset.dims``, and a plain ``axes`` attribute (``"frame,pixel,bin"``) for
readers that do not know dimension scales.
"""

import numpy as np

from ...hdl.event import TIMESTAMP_BITS
from .distance import depth_m, tof_s


__all__ = ["ROW_DATASETS", "DEPTH_DATASETS", "split_of", "create_image", "create_depth",
           "append_image", "append_depth", "read_imager"]

#: Datasets of one row per frame (``complete`` False where never written).
ROW_DATASETS = (("frame", np.uint32), ("shift", np.uint8), ("time_s", np.float64),
                ("complete", np.bool_), ("missing_bins", np.uint32))

#: Datasets of ``/depth`` by frame and pixel, with their types and units.
DEPTH_DATASETS = (("position", np.float32, "bins"), ("depth_m", np.float64, "m"),
                  ("height", np.float32, "counts"), ("background", np.float32, "counts"),
                  ("detected", np.bool_, ""))


def split_of(configuration):
    """``(pixels, first pixel, bin shift)`` of a frame at the registers ``configuration``."""
    pixels = 1 << int(configuration.get("pixel_bits", 0))
    first = int(configuration.get("first_pixel", 0))
    shift = int(configuration.get("bin_shift", 0))
    return pixels, first, shift


def _rows_and_axes(group, pixels, first):
    # The per-frame rows and the pixel axis; returns the frame and pixel scales.
    for name, dtype in ROW_DATASETS:
        group.create_dataset(name, shape=(0,), maxshape=(None,), dtype=dtype, chunks=(1024,))
    group["frame"].make_scale("frame")
    pixel = group.create_dataset("pixel", data=np.arange(first, first + pixels, dtype=np.uint8))
    pixel.attrs["unit"] = "address"
    pixel.make_scale("pixel")
    return group["frame"], pixel


def _attach(dataset, scales, labels):
    for index, (scale, label) in enumerate(zip(scales, labels)):
        dataset.dims[index].label = label
        if scale is not None:
            dataset.dims[index].attach_scale(scale)
    dataset.attrs["axes"] = ",".join(labels)


def create_image(file, configuration, code_s):
    """Make ``/image``: ``counts`` (frame, pixel, bin) and its axes. Returns the bins per
    pixel."""
    pixels, first, shift = split_of(configuration)
    bins = (1 << TIMESTAMP_BITS) >> shift
    group = file.create_group("image")
    frame, pixel = _rows_and_axes(group, pixels, first)
    times = group.create_dataset("bin_time_s",
                                 data=(np.arange(bins) + 0.5) * code_s * (1 << shift))
    times.attrs["unit"] = "s"
    times.make_scale("bin_time_s")
    group.attrs["bin_s"] = code_s * (1 << shift)
    counts = group.create_dataset("counts", shape=(0, pixels, bins),
                                  maxshape=(None, pixels, bins), dtype=np.uint32,
                                  chunks=(1, pixels, bins), compression="gzip",
                                  compression_opts=1)
    _attach(counts, (frame, pixel, times), ("frame", "pixel", "bin"))
    return pixels * bins


def create_depth(file, configuration, code_s):
    """Make ``/depth``: ``position``, ``depth_m``, ``height``, ``background``, ``detected``
    (frame, pixel) and their axes. Returns the pixels of a frame."""
    pixels, first, shift = split_of(configuration)
    group = file.create_group("depth")
    frame, pixel = _rows_and_axes(group, pixels, first)
    group.attrs["bin_s"] = code_s * (1 << shift)
    group.attrs["code_s"] = code_s
    for name, dtype, unit in DEPTH_DATASETS:
        dataset = group.create_dataset(name, shape=(0, pixels), maxshape=(None, pixels),
                                       dtype=dtype, chunks=(max(1, 4096 // pixels), pixels))
        dataset.attrs["unit"] = unit
        _attach(dataset, (frame, pixel), ("frame", "pixel"))
    return pixels


def _append_rows(group, index, item, complete, missing):
    for name, _ in ROW_DATASETS:
        group[name].resize(index + 1, axis=0)
    group["frame"][index] = item.frame
    group["shift"][index] = item.shift
    group["time_s"][index] = item.time_s
    group["missing_bins"][index] = missing
    group["complete"][index] = complete        # last: False marks a row not on the disk


def append_image(file, index, frame, pixels, bins):
    """Write :class:`~fliss.host.stream.HistogramFrame` ``frame`` as row ``index`` of
    ``/image``; False (nothing written) when its split is not the capture's."""
    group = file["image"]
    if len(frame.counts) != pixels * bins or (1 << frame.pixel_bits) != pixels or \
            frame.first_pixel != int(group["pixel"][0]):
        return False
    group["counts"].resize(index + 1, axis=0)
    group["counts"][index] = frame.image
    _append_rows(group, index, frame, frame.complete, frame.missing_bins)
    return True


def append_depth(file, index, frame, pixels, complete=True):
    """Write :class:`~fliss.host.stream.DepthFrame` ``frame`` as row ``index`` of ``/depth``
    (``depth_m`` from its position); False when its pixels are not the capture's."""
    group = file["depth"]
    if len(frame.position) != pixels or frame.first_pixel != int(group["pixel"][0]):
        return False
    detected = np.asarray(frame.detected, dtype=bool)
    position = np.where(detected, np.asarray(frame.position, dtype=float), np.nan)
    values = {"position": position, "height": frame.height, "background": frame.background,
              "detected": detected,
              "depth_m": depth_m(tof_s(position, group.attrs["code_s"] * (1 << frame.shift)))}
    for name, _, _ in DEPTH_DATASETS:
        group[name].resize(index + 1, axis=0)
        group[name][index] = values[name]
    _append_rows(group, index, frame, complete, 0)
    return True


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
