"""The histogram engine: per-pixel TCSPC histograms in two banks, and their readout as packets.

* :mod:`.layout`: widths, limits and the readout layout;
* :mod:`.engine`: :class:`~.engine.Histogram`, events in, frames of banks out;
* :mod:`.frames`: which bank fills, for how long, with which settings;
* :mod:`.banks`: two banks of single-port RAM and the pipeline that counts events;
* :mod:`.dual`: dual-port block RAM banks, one event per cycle;
* :mod:`.readout`: a full bank read bin after bin, cleared as it goes;
* :mod:`.packetizer`: HISTOGRAM and HISTOGRAM_COMPACT packets from the readout, made by
  :mod:`.scanner` (the readout in windows, each weighed compact or full), :mod:`.compact` (the
  tokens of compact chunks) and :mod:`.chunk` (a chunk sent as a packet, also the full-chunk
  packetizer's).
"""
