"""The delay core: pseudorandom delay sources, the pulse scheduler, the laser trigger and TDC start.

* :mod:`.settings`: the delay core's limits;
* :mod:`.modes`: :class:`~.modes.DelayMode` and the table of the delay modes (the settings each
  needs, its largest delay, sequence period, mean delay and label);
* :mod:`.lfsr`: Galois LFSR with a run-time or fixed length;
* :mod:`.trivium`, :mod:`.keyed`: the keystream of the ``keyed`` source;
* :mod:`.source`: the delay source (``off``, ``mseq``, ``masked``, ``keyed``);
* :mod:`.scheduler`: the pulse scheduler (``interval`` and ``grid`` modes);
* :mod:`.laser`: laser trigger and TDC start;
* :mod:`.core`: the delay core, source, scheduler and laser wired together;
* :mod:`.aggressor`: a second, independent trigger for an aggressor illuminator.
"""
