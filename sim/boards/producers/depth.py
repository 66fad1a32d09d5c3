"""The model board's depth frames: one DEPTH packet a frame, as the depth engine sends it
(:mod:`fliss.sim.models.depth`)."""

import numpy as np

from ....hdl.protocol import HISTOGRAM_COUNT_BITS, PacketType
from ....hdl.registers import AcquisitionMode
from ....protocol.depth import depth_payload
from ...models.depth import depth_frame
from .base import Producer


__all__ = ["PRODUCER"]


class DepthProducer(Producer):
    readout = AcquisitionMode.DEPTH
    histograms = True

    def __init__(self):
        self.number = 0     # depth frame number since reset

    def reset(self):
        self.number = 0

    def frame(self, board, counts):
        s = board.settings
        pixel_bits = s["pixel_bits"]
        counts = np.minimum(counts, (1 << HISTOGRAM_COUNT_BITS) - 1).reshape(1 << pixel_bits, -1)
        records = depth_frame(counts, shift=s["bin_shift"], filter=s["depth_filter"],
                              threshold=s["depth_threshold"])
        board._send(PacketType.DEPTH, depth_payload(
            records, frame=self.number, first_pixel=s["first_pixel"], pixel_bits=pixel_bits,
            shift=s["bin_shift"], filter=s["depth_filter"], threshold=s["depth_threshold"]),
            data=True)
        self.number = (self.number + 1) & 0xffffffff
        board.status["frames"] += 1


PRODUCER = DepthProducer
