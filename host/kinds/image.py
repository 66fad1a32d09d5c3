"""Images (capture mode ``"image"``): histograms of several pixels a frame, assembled from the
same chunks as histograms and saved per pixel in ``/image``; exported to PTU."""

import numpy as np

from ...hdl.event import TIMESTAMP_BITS
from ...hdl.registers import AcquisitionMode
from ..imager.files import append_rows, attach, read_imager, rows_and_axes, split_of
from .histogram import HistogramAssembler, HistogramFrame, replay, seen
from .kind import DataKind, extend


__all__ = ["KIND"]


def create(file, configuration, code_s):
    """Make ``/image``: ``counts`` (frame, pixel, bin) and its axes; returns ``(pixels, bins
    per pixel)``."""
    pixels, first, shift = split_of(configuration)
    bins = (1 << TIMESTAMP_BITS) >> shift
    group = file.create_group("image")
    frame, pixel = rows_and_axes(group, pixels, first)
    times = group.create_dataset("bin_time_s",
                                 data=(np.arange(bins) + 0.5) * code_s * (1 << shift))
    times.attrs["unit"] = "s"
    times.make_scale("bin_time_s")
    group.attrs["bin_s"] = code_s * (1 << shift)
    counts = group.create_dataset("counts", shape=(0, pixels, bins),
                                  maxshape=(None, pixels, bins), dtype=np.uint32,
                                  chunks=(1, pixels, bins), compression="gzip",
                                  compression_opts=1)
    attach(counts, (frame, pixel, times), ("frame", "pixel", "bin"))
    return pixels, bins


def fits(file, frame, split):
    """Whether :class:`~fliss.host.stream.HistogramFrame` ``frame`` has the capture's split
    (pixels, first pixel, bins)."""
    pixels, bins = split
    return len(frame.counts) == pixels * bins and (1 << frame.pixel_bits) == pixels and \
        frame.first_pixel == int(file["image/pixel"][0])


def append(file, index, frames, split, completes):
    """Rows ``index …`` of ``/image``, one a frame of ``frames`` (which :func:`fits`; a
    histogram says itself whether it is complete)."""
    group = file["image"]
    extend(group["counts"], index, np.stack([frame.image for frame in frames]))
    append_rows(group, index, frames, [frame.complete for frame in frames],
                [frame.missing_bins for frame in frames])


def blank(number, configuration):
    """The row of a frame that never arrived: zeros, marked incomplete."""
    pixels, first, shift = split_of(configuration)
    bins = (1 << TIMESTAMP_BITS) >> shift
    return HistogramFrame(number, shift, np.zeros(pixels * bins, np.uint32), False,
                          pixels * bins, float("nan"), pixels.bit_length() - 1, first)


def read(file, group_of, rows_of, problems):
    """The frames of ``/image``: ``histograms`` ``(N, pixels, bins)``, their rows and the
    pixels."""
    columns = read_imager(group_of(file, "image"), ["counts"], rows_of, problems)
    return {"histograms": columns["counts"], "frames": columns["frame"],
            "shifts": columns["shift"], "times_s": columns["time_s"],
            "complete": columns["complete"], "pixels": columns["pixel"]}


def tally(totals, item):
    """A saved frame's photons."""
    totals.events += int(item.counts.sum())


KIND = DataKind(
    name="image", rank=1, readout=AcquisitionMode.HISTOGRAM, packet="histogram",
    assembler=HistogramAssembler, item=HistogramFrame, rows="images", format_version=3,
    what="per-pixel histograms", counted=True, imager=True,
    create=create, fits=fits, append=append, blank=blank, read=read, tally=tally, replay=replay,
    seen=seen, exports=("ptu",))
