"""The link: a UART carrying framed, checked packets (``docs/protocol.md``) to and from the
command processor and the data packetizers (:mod:`fliss.hdl.packets`).

* :mod:`.uart`: UART transmitter and receiver;
* :mod:`.crc`: the CRC-16, appended and checked as stream stages;
* :mod:`.cobs`: COBS encoder and decoder stream stages;
* :mod:`.framing`: frame encoder and decoder, packets to and from the stages above;
* :mod:`.buffer`: a stream buffer in block RAM;
* :mod:`.command`: the command processor (register file access, status, NAKs);
* :mod:`.arbiter`: merges packet streams onto the link;
* :mod:`.link`: :class:`~.link.Link`, the UART, the frames, the command processor and the
  arbiter as one block.

The blocks a design of your own reuses are importable from here::

    from fliss.hdl.link import Link
"""

from ..lazy import lazy_names


#: The public names, by the module that defines them, imported when first asked for (PEP 562),
#: as in :mod:`fliss.hdl.delay`.
_PUBLIC = {
    "Link": ".link", "PacketBeat": ".framing",
}

__all__ = list(_PUBLIC)

__getattr__, __dir__ = lazy_names(__name__, _PUBLIC)
