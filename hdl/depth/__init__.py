"""The depth engine: a DEPTH packet per frame from the histogram readout (``docs/depth.md``).

* :mod:`.engine`: :class:`~.engine.DepthEngine`, the blocks below wired to the readout;
* :mod:`.peak`: the box filter and strongest window of each pixel;
* :mod:`.record`: a pixel's record (position, height, background) from its peak search.

Its packetizer, the records of a frame stored and sent after a header, is
:mod:`fliss.hdl.packets.depth`, with the other data packetizers.
"""
