"""DEPTH packets: a frame's header and per-pixel records (``docs/depth.md``), packed and unpacked
from the layouts of :mod:`fliss.hdl.protocol`, and the range of the settings a header carries."""

import numpy as np
from amaranth.lib import data

from ..hdl.histogram.engine import MAX_SHIFT
from ..hdl.protocol import (DepthHeader, DepthRecord, DEPTH_HEADER_BYTES, DEPTH_RECORD_BYTES,
                            DEPTH_PIXELS)
from ..hdl.registers import DEPTH
from .layout import pack, unpack_from


__all__ = ["RECORD_DTYPE", "BACKGROUND_MAX", "check_depth_settings", "depth_payload",
           "unpack_depth"]


#: The fields of a :class:`~fliss.hdl.protocol.DepthRecord`, as the engine makes them.
RECORD_DTYPE = np.dtype([("position", np.int64), ("detected", np.bool_),
                         ("height", np.int64), ("background", np.int64)])

#: Largest ``background`` (it saturates there).
BACKGROUND_MAX = (1 << data.Layout.cast(DepthRecord)["background"].width) - 1

_FILTER = DEPTH.register("filter")
_THRESHOLD = DEPTH.register("threshold")


def check_depth_settings(*, shift, filter, threshold, pixel_bits=0, first_pixel=0):
    """Raise :exc:`ValueError` with one clear line unless the depth settings are valid."""
    for name, value, low, high in (("Bin shift", shift, 0, MAX_SHIFT),
                                   ("Depth filter", filter, _FILTER.minimum, _FILTER.maximum),
                                   ("Depth threshold", threshold, _THRESHOLD.minimum,
                                    _THRESHOLD.maximum),
                                   ("Pixel bits", pixel_bits, 0, 6),
                                   ("First pixel", first_pixel, 0, DEPTH_PIXELS - 1)):
        if not isinstance(value, (int, np.integer)) or not low <= value <= high:
            raise ValueError(f"{name} must be an integer from {low} to {high}, not {value!r}")
    if first_pixel + (1 << pixel_bits) > DEPTH_PIXELS:
        raise ValueError(f"First pixel {first_pixel} plus {1 << pixel_bits} pixels is beyond "
                         f"the {DEPTH_PIXELS} pixels of a frame")


def depth_payload(records, *, frame, first_pixel, pixel_bits, shift, filter, threshold):
    """The payload of the DEPTH packet of one frame: its :class:`DepthHeader` and ``records``
    (:data:`RECORD_DTYPE`, ``2**pixel_bits`` of them), as the gateware sends it."""
    check_depth_settings(shift=shift, filter=filter, threshold=threshold,
                         pixel_bits=pixel_bits, first_pixel=first_pixel)
    if len(records) != 1 << pixel_bits:
        raise ValueError(f"A frame of 2**{pixel_bits} pixels needs {1 << pixel_bits} records, "
                         f"not {len(records)}")
    head = pack(DepthHeader, frame=frame & 0xffffffff, first_pixel=first_pixel,
                pixel_bits=pixel_bits, shift=shift, filter=filter, threshold=threshold)
    return head + b"".join(
        pack(DepthRecord, position=int(r["position"]), detected=int(r["detected"]),
             height=int(r["height"]), background=int(r["background"])) for r in records)


def unpack_depth(payload):
    """The header (a dict of :class:`DepthHeader` fields) and records (:data:`RECORD_DTYPE`) of
    a DEPTH payload; raises :exc:`ValueError` with one line for a malformed one."""
    payload = bytes(payload)
    if len(payload) < DEPTH_HEADER_BYTES:
        raise ValueError(f"DEPTH payload of {len(payload)} bytes is shorter than its "
                         f"{DEPTH_HEADER_BYTES}-byte header")
    head = unpack_from(DepthHeader, payload)
    if head["pixel_bits"] > 6 or head["shift"] > MAX_SHIFT or \
            head["first_pixel"] + (1 << min(head["pixel_bits"], 6)) > DEPTH_PIXELS:
        raise ValueError(f"DEPTH header out of range: {head['pixel_bits']} pixel bits, first "
                         f"pixel {head['first_pixel']}, bin shift {head['shift']}")
    pixels = 1 << head["pixel_bits"]
    expected = DEPTH_HEADER_BYTES + pixels * DEPTH_RECORD_BYTES
    if len(payload) != expected:
        raise ValueError(f"DEPTH payload of {len(payload)} bytes, not {expected} for "
                         f"{pixels} pixels")
    raw = np.frombuffer(payload, np.uint8, offset=DEPTH_HEADER_BYTES).reshape(
        pixels, DEPTH_RECORD_BYTES)
    words = np.zeros((pixels, 8), np.uint8)
    words[:, :DEPTH_RECORD_BYTES] = raw
    words = words.view("<u8")[:, 0]
    records = np.zeros(pixels, RECORD_DTYPE)
    for name, field in data.Layout.cast(DepthRecord):
        value = (words >> np.uint64(field.offset)) & np.uint64((1 << field.width) - 1)
        records[name] = value.astype(RECORD_DTYPE[name])
    return head, records
