"""Widths, limits and the readout layout of the histogram engine (:mod:`fliss.hdl.histogram.engine`)."""

from amaranth.hdl import Shape
from amaranth.lib import data

from ..event import ADDRESS_BITS, TIMESTAMP_BITS
from ..registers import HISTOGRAM
from ..delay.settings import BANK_BITS, MAX_BANK_BITS


__all__ = ["BANK_BITS", "MAX_BANK_BITS", "PIXEL_BITS", "PIXEL_SETTING_BITS", "BIN_BITS",
           "COUNT_WIDTH", "MIN_COUNT_WIDTH", "MAX_COUNT_WIDTH", "MAX_SHIFT",
           "INTEGRATION_WIDTH", "HistogramSettings", "ReadoutSplit", "readout_layout"]


#: Widest bin index of a pixel: one bin per timestamp code, 8192 bins.
BIN_BITS = TIMESTAMP_BITS
#: Width of a pixel index within a frame (up to 64 pixels: the sensor's addresses).
PIXEL_BITS = ADDRESS_BITS
#: Width of the ``pixel_bits`` setting.
PIXEL_SETTING_BITS = Shape.cast(HISTOGRAM.layout()["pixel_bits"].shape).width
#: Default width of a bin count, in bits.
COUNT_WIDTH = 16
#: Narrowest bin count, in bits.
MIN_COUNT_WIDTH = 16
#: Widest bin count, in bits.
MAX_COUNT_WIDTH = 32
#: Largest bin shift: with it every timestamp falls in bin 0.
MAX_SHIFT = TIMESTAMP_BITS
#: Width of the integration time setting (its register's): up to 53 s at 80 MHz.
INTEGRATION_WIDTH = HISTOGRAM.register("integration").width

#: Settings of a :class:`~fliss.hdl.histogram.engine.Histogram`: ``bin_shift`` (bins are
#: ``2**bin_shift`` timestamp codes wide) and ``integration`` (frame length in clock cycles); the
#: layout of the register group :data:`~fliss.hdl.registers.HISTOGRAM`.
HistogramSettings = HISTOGRAM.layout()
assert HistogramSettings.size >= (MAX_SHIFT.bit_length() + INTEGRATION_WIDTH)


class ReadoutSplit(data.Struct):
    """How the frame being read out splits its bank: bins ``2**shift`` timestamp codes wide,
    ``2**pixel_bits`` pixels from address ``first_pixel``
    (:attr:`~fliss.hdl.histogram.engine.Histogram` ``readout_split``)."""
    shift:       range(MAX_SHIFT + 1)
    pixel_bits:  PIXEL_SETTING_BITS
    first_pixel: PIXEL_BITS


def readout_layout(bank_bits=BANK_BITS, count_width=COUNT_WIDTH):
    """Payload of :attr:`~.engine.Histogram.readout`: flat bin index (``pixel << (13 - bin_shift) |
    bin``), count, last bin of the frame."""
    return data.StructLayout({
        "index": bank_bits,
        "count": count_width,
        "last":  1,
    })
