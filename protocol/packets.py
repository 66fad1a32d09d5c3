"""The kinds of data packet (:data:`fliss.hdl.protocol.DATA_PACKETS`), as the software sees them.

A board sends data packets unasked while it acquires; every other packet it sends is a reply.
:data:`DATA_TYPES` tells the two apart; :data:`KIND` names what a data packet carries
(``"events"``, ``"histogram"``, ``"depth"``), and :data:`HISTOGRAM_TYPES` are the packets that
carry histogram chunks (decoded by :func:`fliss.protocol.histograms.decode_chunk`). The host
finds the assembler of each kind of data packet in :mod:`fliss.host.kinds`, the model board
the producer of each readout in :mod:`fliss.sim.boards.producers`.
"""

from ..hdl.protocol import DATA_PACKETS, PacketType


__all__ = ["KIND", "DATA_TYPES", "HISTOGRAM_TYPES"]


#: The kind of data of each data packet type.
KIND = dict(DATA_PACKETS)

#: The data packet types.
DATA_TYPES = frozenset(KIND)

#: The packet types that carry histogram chunks: those of HISTOGRAM's kind.
HISTOGRAM_TYPES = frozenset(type for type, kind in KIND.items()
                            if kind == KIND[PacketType.HISTOGRAM])
