"""The imager's data on the host: per-pixel histograms and depth frames.

* :mod:`.results`: :class:`~.results.Images` and :class:`~.results.DepthFrames`, numpy arrays;
* :mod:`.distance`: time of flight and depth from a peak's position;
* :mod:`.files`: the parts of their groups in a capture file that images and depth frames share
  (each kind's own are in :mod:`fliss.host.kinds`);
* :mod:`.analysis`: per-pixel peaks and depths;
* :mod:`.threshold`: the depth threshold that suits a pixel split;
* :mod:`.report`: tables and figures of an imager capture;
* :mod:`.demo`: the imager's part of ``fliss demo``.
"""
