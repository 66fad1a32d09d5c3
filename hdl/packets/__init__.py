"""The data packetizers, one block per file: the packets a board sends unasked while it acquires
(:data:`fliss.hdl.protocol.DATA_PACKETS`), each made from its acquisition stream.

* :mod:`.events`: EVENTS packets, raw event batches from the raw-event FIFO;
* :mod:`.histogram`: HISTOGRAM and HISTOGRAM_COMPACT packets from a histogram readout, whichever
  is shorter (made by :mod:`fliss.hdl.histogram.scanner`, :mod:`~fliss.hdl.histogram.compact`
  and :mod:`~fliss.hdl.histogram.chunk`);
* :mod:`.histogram_full`: HISTOGRAM packets only, the same ports, for the smallest builds;
* :mod:`.depth`: a DEPTH packet per frame, the depth engine's records after a header.

A new kind of data packet adds its packetizer here; the top level (:mod:`fliss.hdl.top`)
connects it to the link's arbiter.
"""
