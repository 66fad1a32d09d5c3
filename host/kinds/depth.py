"""Depth frames (capture mode ``"depth"``): DEPTH packets, a frame each, saved by frame and
pixel in ``/depth``; no export format holds them."""

from dataclasses import dataclass
from typing import Optional

import numpy as np

from ...hdl.protocol import DEPTH_FRACTION_BITS, DEPTH_BACKGROUND_FRACTION_BITS
from ...hdl.registers import AcquisitionMode
from ...protocol.depth import unpack_depth
from ..imager.distance import depth_m, tof_s
from ..imager.files import append_rows, attach, read_imager, rows_and_axes, split_of
from .histogram import frame_rows
from .kind import DataKind, Seen, extend


__all__ = ["DepthFrame", "depth_frame_of", "DepthAssembler", "DEPTH_DATASETS", "KIND"]


@dataclass
class DepthFrame:
    """One depth frame (a DEPTH packet): per pixel, its strongest peak.

    Pixel ``p`` of the arrays is the sensor's address ``first_pixel + p``. ``position`` is the
    peak's centre in bins of ``2**shift`` timestamp codes from the start of bin 0 (bin ``j``
    spans ``j … j + 1``), NaN where ``detected`` is False; ``height`` the filtered peak above
    background, in counts; ``background`` the mean count per bin outside the peak window.
    ``records`` holds the packet's integers as sent (``position`` in 1/16 bin, also where not
    detected; ``background`` in 1/16 count), ``filter`` and ``threshold`` the settings it was
    made with. ``time_s`` is the host's receive time.
    """
    frame: int
    first_pixel: int
    shift: int
    position: np.ndarray
    height: np.ndarray
    background: np.ndarray
    detected: np.ndarray
    time_s: float
    pixel_bits: int = 0
    filter: int = 0
    threshold: int = 0
    records: Optional[np.ndarray] = None


def depth_frame_of(payload: bytes, time_s: float) -> DepthFrame:
    """The :class:`DepthFrame` of a DEPTH payload; raises :exc:`ValueError` with one line for
    a malformed one."""
    head, records = unpack_depth(payload)
    detected = records["detected"].copy()
    position = records["position"] / (1 << DEPTH_FRACTION_BITS)
    position[~detected] = np.nan
    return DepthFrame(head["frame"], head["first_pixel"], head["shift"], position,
                      records["height"].copy(),
                      records["background"] / (1 << DEPTH_BACKGROUND_FRACTION_BITS), detected,
                      time_s, head["pixel_bits"], head["filter"], head["threshold"], records)


class DepthAssembler:
    """A :class:`DepthFrame` of each DEPTH packet; a malformed one is counted and dropped (its
    reason in the stream's ``last_malformed``), a jump in frame numbers counts the frames lost
    in ``lost_depth_frames``."""

    COUNTERS = ("depth_frames", "lost_depth_frames")
    FRAMES = "depth_frames"

    def __init__(self, stream):
        self.stream = stream
        self._next = None

    def add(self, packet, time_s):
        stream, counters = self.stream, self.stream.counters
        try:
            frame = depth_frame_of(packet.payload, time_s)
        except ValueError as error:
            counters.malformed += 1
            stream.last_malformed = str(error)
            return []
        if self._next is not None and frame.frame != self._next:
            counters.lost_depth_frames += (frame.frame - self._next) % (1 << 32)
        self._next = stream.frames_ended = (frame.frame + 1) % (1 << 32)
        counters.depth_frames += 1
        return [frame]

    def flush(self, time_s=None):
        return []


#: Datasets of ``/depth`` by frame and pixel, with their types and units.
DEPTH_DATASETS = (("position", np.float32, "bins"), ("depth_m", np.float64, "m"),
                  ("height", np.float32, "counts"), ("background", np.float32, "counts"),
                  ("detected", np.bool_, ""))


def create(file, configuration, code_s):
    """Make ``/depth``: ``position``, ``depth_m``, ``height``, ``background``, ``detected``
    (frame, pixel) and their axes. Returns the pixels of a frame."""
    pixels, first, shift = split_of(configuration)
    group = file.create_group("depth")
    frame, pixel = rows_and_axes(group, pixels, first)
    group.attrs["bin_s"] = code_s * (1 << shift)
    group.attrs["code_s"] = code_s
    for name, dtype, unit in DEPTH_DATASETS:
        dataset = group.create_dataset(name, shape=(0, pixels), maxshape=(None, pixels),
                                       dtype=dtype, chunks=(max(1, 4096 // pixels), pixels))
        dataset.attrs["unit"] = unit
        attach(dataset, (frame, pixel), ("frame", "pixel"))
    return pixels


def fits(file, frame, pixels):
    """Whether :class:`DepthFrame` ``frame`` has the capture's pixels."""
    return len(frame.position) == pixels and frame.first_pixel == int(file["depth/pixel"][0])


def append(file, index, frames, pixels, completes):
    """Rows ``index …`` of ``/depth``, one a :class:`DepthFrame` of ``frames`` (which
    :func:`fits`; ``depth_m`` from its position); ``completes`` False marks a frame that never
    arrived."""
    group = file["depth"]
    detected = np.stack([np.asarray(frame.detected, dtype=bool) for frame in frames])
    position = np.where(detected, np.stack([np.asarray(frame.position, dtype=float)
                                            for frame in frames]), np.nan)
    bin_s = group.attrs["code_s"] * (1 << np.array([frame.shift for frame in frames]))
    values = {"position": position, "height": np.stack([frame.height for frame in frames]),
              "background": np.stack([frame.background for frame in frames]),
              "detected": detected, "depth_m": depth_m(tof_s(position, bin_s[:, None]))}
    for name, _, _ in DEPTH_DATASETS:
        extend(group[name], index, values[name])
    append_rows(group, index, frames, completes, [0] * len(frames))


def blank(number, configuration):
    """The row of a frame that never arrived: nothing detected."""
    pixels, first, shift = split_of(configuration)
    nan = np.full(pixels, np.nan)
    return DepthFrame(number, first, shift, nan, nan, nan, np.zeros(pixels, bool),
                      float("nan"))


def read(file, group_of, rows_of, problems):
    """The frames of ``/depth``: their rows, the pixels and the arrays by name (``depth``)."""
    names = [name for name, _, _ in DEPTH_DATASETS]
    columns = read_imager(group_of(file, "depth"), names, rows_of, problems)
    return {"histograms": np.zeros((0, 0, 0), dtype=np.uint32), "frames": columns["frame"],
            "shifts": columns["shift"], "times_s": columns["time_s"],
            "complete": columns["complete"], "pixels": columns["pixel"],
            "depth": {name: columns[name] for name in ("position", "depth_m", "height",
                                                       "background", "detected")}}


def replay(capture):
    """The :class:`DepthFrame` of each row of ``capture``."""
    pixels = capture.pixels
    first = int(pixels[0]) if len(pixels) else 0
    pixel_bits = int(len(pixels)).bit_length() - 1 if len(pixels) else 0
    depth = capture.depth
    for index, frame, _, shift, time_s in frame_rows(capture):
        detected = np.asarray(depth["detected"][index], dtype=bool)
        yield DepthFrame(frame, first, shift, np.asarray(depth["position"][index]),
                         np.asarray(depth["height"][index]),
                         np.asarray(depth["background"][index]), detected, time_s, pixel_bits)


def seen(item, shift):
    """A depth frame in the live view: a numbered frame, drawn as it is, no photons."""
    return Seen(item.frame, True, None, 0, True)


def tally(totals, item):
    """A saved frame's detections, its highest peak and its threshold."""
    totals.detections += int(item.detected.sum())
    totals.highest = max(totals.highest, int(item.height.max()))
    totals.threshold = item.threshold


KIND = DataKind(
    name="depth", rank=2, readout=AcquisitionMode.DEPTH, packet="depth",
    assembler=DepthAssembler, item=DepthFrame, rows="depth frames", format_version=3,
    what="depth frames", counted=False, imager=True,
    create=create, fits=fits, append=append, blank=blank, read=read, tally=tally,
    replay=replay, seen=seen, exports=("ply", "pcd", "las", "mcap", "mcap-ros2"),
    refusal="PTU and Photon-HDF5 hold photons and TCSPC histograms, not depth frames: a depth "
            "capture goes to a point cloud (--to ply, pcd, las, mcap or mcap-ros2; "
            "docs/point-clouds.md)")
