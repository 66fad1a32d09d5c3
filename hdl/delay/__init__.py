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

The blocks and definitions a design of your own reuses are importable from here::

    from fliss.hdl.delay import DelayCore, DelayMode, DelaySettings, delay_problems
"""

from ..lazy import lazy_names


#: The public names, by the module that defines them. They are imported when first asked for
#: (PEP 562): the register map imports this package's definitions (:mod:`.modes`,
#: :mod:`.settings`), and the blocks import the register map, so importing the blocks here
#: would make a circle.
_PUBLIC = {
    "DelayCore": ".core", "PulseScheduler": ".scheduler", "DelaySource": ".source",
    "Delay": ".source", "LaserTrigger": ".laser", "Aggressor": ".aggressor",
    "DelayMode": ".modes", "delay_problems": ".modes", "DelaySettings": "..registers",
}

__all__ = list(_PUBLIC)

__getattr__, __dir__ = lazy_names(__name__, _PUBLIC)
