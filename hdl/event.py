"""Layout of one detected photon, as the sensor's TDC interface delivers it.

The sensor of the paper (Figure 6, Table 1) gives per photon a 13-bit timestamp (50 ps LSB,
8192 codes, about 409.6 ns) measured from the TDC start, a 6-bit pixel address and a collision
flag. The interface adds the index of the laser cycle (pulse) the event belongs to.

This one definition serves the gateware (:class:`Event` is an ``amaranth.lib.data.Struct``), the
models and the host (:data:`fliss.protocol.events.EVENT_DTYPE` is derived from it).
"""

from amaranth.lib import data


__all__ = ["TIMESTAMP_BITS", "ADDRESS_BITS", "PULSE_BITS", "TDC_LSB_S", "Event"]


#: Timestamp width in bits: 8192 codes.
TIMESTAMP_BITS = 13
#: Pixel address width in bits: 64 addresses for the 60 pixels of the column.
ADDRESS_BITS = 6
#: Width of the laser cycle index, in bits.
PULSE_BITS = 32
#: Timestamp LSB of the sensor's TDC, in seconds.
TDC_LSB_S = 50e-12


class Event(data.Struct):
    """One photon event: TDC timestamp, pixel address, collision flag, laser cycle index."""
    timestamp: TIMESTAMP_BITS
    address:   ADDRESS_BITS
    collision: 1
    pulse:     PULSE_BITS
