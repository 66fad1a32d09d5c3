"""The software half of the FLISS link (``docs/protocol.md``), for the host and the models alike.

Everything about the format comes from :mod:`fliss.hdl.protocol`; this package implements it:

* :mod:`.layout`: payloads from and to the values of their layouts; arrays of words;
* :mod:`.crc`, :mod:`.cobs`: the CRC-16 and the COBS encoding;
* :mod:`.frames`: packets to wire frames and back, a streaming frame decoder;
* :mod:`.events`: EVENTS payloads as numpy arrays;
* :mod:`.histograms`: HISTOGRAM and HISTOGRAM_COMPACT chunks, encoded and assembled;
* :mod:`.depth`: DEPTH payloads;
* :mod:`.packets`: the kinds of data packet, and the decoder of each.

The names of :mod:`.layout`, :mod:`.crc`, :mod:`.cobs`, :mod:`.frames` and the event payloads are
gathered here: ``protocol.encode_frame(...)``.
"""

from .cobs import CobsError, cobs_decode, cobs_encode
from .crc import CRC_TABLE, crc16
from .events import EVENT_DTYPE, pack_events, unpack_events
from .frames import (FrameDecoder, LinkCounters, LinkError, Packet, PacketEncoder, Resync,
                     SequenceGap, decode_frame, decode_packet, encode_frame, encode_packet,
                     packet_type)
from .layout import byte_size, pack, pack_words, unpack, unpack_from, unpack_words, word_dtype


__all__ = ["CobsError", "cobs_decode", "cobs_encode", "CRC_TABLE", "crc16", "EVENT_DTYPE",
           "pack_events", "unpack_events", "FrameDecoder", "LinkCounters", "LinkError", "Packet",
           "PacketEncoder", "Resync", "SequenceGap", "decode_frame", "decode_packet",
           "encode_frame", "encode_packet", "packet_type", "byte_size", "pack", "pack_words",
           "unpack", "unpack_from", "unpack_words", "word_dtype"]
