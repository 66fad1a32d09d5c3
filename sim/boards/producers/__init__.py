"""The model board's producers, one per readout (``acquisition`` setting): the data packets the
gateware's packetizer of that readout sends, made from the simulated events
(:class:`~.base.Producer`).

* :mod:`.histogram`: HISTOGRAM and HISTOGRAM_COMPACT chunks;
* :mod:`.depth`: DEPTH packets;
* :mod:`.events`: EVENTS packets.

A new kind of data is a new module here: every module of this package but :mod:`.base` is
read for its ``PRODUCER``.
"""

import importlib
import pkgutil


__all__ = ["PRODUCERS"]


def _discover():
    found = {}
    for module in pkgutil.iter_modules(__path__):
        if module.name != "base":
            producer = importlib.import_module(f".{module.name}", __name__).PRODUCER
            found[producer.readout] = producer
    return found


#: The producer class of each readout (``AcquisitionMode``).
PRODUCERS = _discover()
