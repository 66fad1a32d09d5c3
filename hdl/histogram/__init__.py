"""The histogram engine: per-pixel TCSPC histograms in two banks, and their readout as packets.

* :mod:`.layout`: widths, limits and the readout layout;
* :mod:`.engine`: :class:`~.engine.Histogram`, events in, frames of banks out;
* :mod:`.frames`: which bank fills, for how long, with which settings;
* :mod:`.banks`: two banks of single-port RAM and the pipeline that counts events;
* :mod:`.dual`: dual-port block RAM banks, one event per cycle;
* :mod:`.readout`: a full bank read bin after bin, cleared as it goes;
* the parts of the readout's packets: :mod:`.scanner` (the readout in windows, each weighed
  compact or full), :mod:`.compact` (the tokens of compact chunks) and :mod:`.chunk` (a chunk
  sent as a packet); the packetizers that use them are :mod:`fliss.hdl.packets.histogram` and
  :mod:`fliss.hdl.packets.histogram_full`.

The blocks a design of your own reuses are importable from here::

    from fliss.hdl.histogram import Histogram, HistogramSettings
"""

from ..lazy import lazy_names


#: The public names, by the module that defines them, imported when first asked for (PEP 562),
#: as in :mod:`fliss.hdl.delay`.
_PUBLIC = {
    "Histogram": ".engine", "HistogramSettings": ".layout", "ReadoutSplit": ".layout",
    "readout_layout": ".layout",
}

__all__ = list(_PUBLIC)

__getattr__, __dir__ = lazy_names(__name__, _PUBLIC)
