"""The model board's histograms: a frame's HISTOGRAM and HISTOGRAM_COMPACT chunks, as the
gateware's histogram packetizer makes them (:func:`fliss.protocol.histograms.encode_histogram`)."""

from ....hdl.registers import AcquisitionMode
from ....protocol.histograms import encode_histogram
from .base import Producer


__all__ = ["PRODUCER"]


class HistogramProducer(Producer):
    readout = AcquisitionMode.HISTOGRAM
    histograms = True

    def __init__(self):
        #: Number the next histogram will carry (from 0 since reset).
        self.number = 0

    def reset(self):
        self.number = 0

    def frame(self, board, counts):
        s = board.settings
        for type, payload in encode_histogram(counts, frame=self.number, shift=s["bin_shift"],
                                              pixel_bits=s.get("pixel_bits", 0),
                                              first_pixel=s.get("first_pixel", 0),
                                              full_readout=s.get("full_readout", 0)):
            board._send(type, payload, data=True)
        self.number += 1
        board.status["frames"] += 1


PRODUCER = HistogramProducer
