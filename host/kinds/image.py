"""Images (capture mode ``"image"``): histograms of several pixels a frame, assembled from the
same chunks as histograms and saved per pixel in ``/image``; exported to PTU."""

import numpy as np

from ...hdl.event import TIMESTAMP_BITS
from ...hdl.registers import AcquisitionMode
from ..imager.files import append_image, create_image, read_imager, split_of
from .histogram import HistogramAssembler, HistogramFrame, replay, seen
from .kind import DataKind


__all__ = ["KIND"]


def create(file, configuration, code_s):
    """``/image`` and its axes; returns ``(pixels, bins per pixel)``."""
    bins = create_image(file, configuration, code_s)
    pixels = len(file["image/pixel"])
    return pixels, bins // pixels


def append(file, index, frame, split, complete=True):
    """Row ``index`` of ``/image`` (a histogram says itself whether it is complete)."""
    return append_image(file, index, frame, *split)


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
    create=create, append=append, blank=blank, read=read, tally=tally, replay=replay,
    seen=seen, exports=("ptu",))
