"""Bulk decoding of link bytes with numpy: recordings, and large reads from a board.

:class:`~fliss.protocol.FrameDecoder` decodes one frame at a time in Python: right for
replies, slow for raw events (about 1.5 µs per event). :class:`BulkDecoder` is a
:class:`~fliss.protocol.FrameDecoder` that decodes all complete frames of a read at once:
it returns the same packets and reports in the same order and keeps the same counters, for any
input. :meth:`BulkDecoder.feed_events` returns the events of all EVENTS packets as one
``EVENT_DTYPE`` array instead of one packet per frame; :func:`decode_stream` decodes a whole
recording.

How, for the complete frames of one read:

* delimiters are found with :func:`numpy.flatnonzero`; frames are grouped by encoded length, and
  each group becomes a 2-D array with one row per frame. Full EVENTS frames all have the same
  length, so a stream of raw events is one group;
* COBS: the code bytes of all rows are followed together, one block per step (as many steps as
  the frame with the most blocks has blocks), and become zeros in place; a row whose chain of
  blocks does not end on its delimiter is ``TRUNCATED``;
* CRC: every frame is checked. One column of :data:`~fliss.hdl.protocol.CRC_BYTES` bytes per
  step for all rows at once: a CRC register as wide as the column is replaced by a lookup,
  ``crc = table[crc ^ column]``, with a table of ``2**CRC_WIDTH`` entries built from the host
  codec's byte table;
* header fields and event fields are unpacked with shifts and masks over whole columns.

Frames the bulk path leaves alone go through :func:`~fliss.protocol.decode_frame`, one by
one: frames of a length shared by fewer than ``min_group`` frames of the read (replies, noise),
frames too long or too short to be a packet, and frames with a full 254-byte COBS block (their
decoded length is not their encoded length minus one). Sequence numbers, counters and the order
of what is reported are then worked out over all frames together.
"""

import itertools
from dataclasses import dataclass

import numpy as np
from amaranth.lib import data

from ..hdl.protocol import (DELIMITER, COBS_MAX_RUN, CRC_WIDTH, CRC_INIT, CRC_BYTES, PacketType,
                            Header, HEADER_BYTES, MAX_PACKET, MAX_ENCODED, NakCode, EVENT_BYTES)
from ..protocol import events as _event
from ..protocol.crc import CRC_TABLE
from ..protocol.frames import (FrameDecoder, LinkError, Packet, SequenceGap, decode_frame,
                               packet_type)


__all__ = ["BULK_MIN_BYTES", "BULK_MIN_GROUP", "Decoded", "BulkDecoder", "decode_stream"]


#: Reads shorter than this many bytes go to the scalar decoder (numpy's overhead per call would
#: cost more than it saves).
BULK_MIN_BYTES = 4096

#: Frames of one length are decoded in bulk when a read holds at least this many of them.
BULK_MIN_GROUP = 16


# One column of CRC_BYTES bytes per step needs a register of CRC_BYTES whole bytes and a table of
# 2**CRC_WIDTH entries.
assert CRC_WIDTH == 8 * CRC_BYTES == 16, "the bulk CRC is written for a 16-bit CRC"
assert EVENT_BYTES <= 8, "events are unpacked from 64-bit words"

_CRC_MASK = (1 << CRC_WIDTH) - 1
_CRC_TOP = CRC_WIDTH - 8
_BYTE_TABLE = np.array(CRC_TABLE, dtype=np.uint16)
_word_table = None


def _column_table():
    """``table[x]``: the CRC register after :data:`CRC_BYTES` zero bytes, starting from ``x``.
    Then, from register ``crc``, the bytes of the big-endian column ``w`` leave ``table[crc ^ w]``
    (the CRC is linear, and the column fills the register)."""
    global _word_table
    if _word_table is None:
        crc = np.arange(1 << CRC_WIDTH, dtype=np.uint32)
        for _ in range(CRC_BYTES):
            crc = ((crc << 8) & _CRC_MASK) ^ _BYTE_TABLE[crc >> _CRC_TOP]
        _word_table = crc.astype(np.uint16)
    return _word_table


def crc_rows(packets):
    """The CRC (as :func:`fliss.protocol.crc16` computes it) of each row of ``packets``, a
    2-D ``uint8`` array; a ``uint16`` array."""
    packets = np.asarray(packets, dtype=np.uint8)
    rows, length = packets.shape
    crc = np.full(rows, CRC_INIT, dtype=np.uint16)
    lead = length % CRC_BYTES
    for column in range(lead):
        crc = ((crc << 8) & _CRC_MASK) ^ _BYTE_TABLE[(crc >> _CRC_TOP) ^ packets[:, column]]
    # One contiguous row of native integers per column, so that each step reads a whole row.
    words = np.ascontiguousarray(packets[:, lead:]).view(f">u{CRC_BYTES}") \
        .T.astype(np.uint16, order="C")
    table = _column_table()
    index = np.empty(rows, dtype=np.uint16)
    for column in words:
        np.bitwise_xor(crc, column, out=index)
        table.take(index, out=crc, mode="clip")
    return crc


_HEADER_LAYOUT = data.Layout.cast(Header)
_SEQ_MODULUS = 1 << _HEADER_LAYOUT["seq"].width
_EVENTS = PacketType.EVENTS.value
_KEEP = FrameDecoder._KEEP


def _header_field(value, name):
    field = _HEADER_LAYOUT[name]
    return ((value >> np.uint64(field.offset)) & np.uint64((1 << field.width) - 1)).astype(np.int64)


def _decode_group(buf, starts, length):
    """Decode frames that all have ``length`` encoded bytes, starting at ``starts`` in ``buf``
    (each is followed by its delimiter).

    Returns ``rows`` (one row per frame: the decoded packet at columns ``1 … length - 1``),
    ``code`` (0 for a good packet, else a :class:`NakCode` value), ``type``, ``seq`` and
    ``scalar``, the rows that need the scalar decoder (a full COBS block).
    """
    count = len(starts)
    # Each row: the frame, its delimiter, and room for a jump past the delimiter (zeros).
    width = length + 1 + COBS_MAX_RUN + 1
    rows = np.zeros((count, width), dtype=np.uint8)
    if count > 1 and np.all(np.diff(starts) == length + 1):     # back to back: a plain view
        rows[:, :length + 1] = buf[starts[0]:starts[0] + count * (length + 1)] \
            .reshape(count, length + 1)
    else:
        rows[:, :length + 1] = buf[starts[:, None] + np.arange(length + 1)]
    flat = rows.reshape(-1)

    # COBS: follow the chain of code bytes of every row at once. A code byte says where the next
    # one is; the chain must land on the delimiter. A row stops (code 0) at its delimiter or, if
    # it jumped past it, in the zeros after it (cut short).
    at = np.arange(count) * width
    end = at + length
    # A full block (code 0xff) adds no zero: such rows go to the scalar decoder. Only a code
    # byte at most length - 0xff bytes into the frame can start one that ends in time, and the
    # chain reaches it in at most as many steps.
    full_steps = length - COBS_MAX_RUN
    scalar = np.zeros(count, dtype=bool)
    step = np.empty(count, dtype=np.uint8)
    for number in itertools.count():
        flat.take(at, out=step)
        if number < full_steps:
            scalar |= step == COBS_MAX_RUN + 1
        flat[at] = 0            # a code byte stands for a zero (the first one is cut off)
        np.add(at, step, out=at, casting="unsafe")
        if number % 8 == 7 and not step.any():     # all chains ended (checked now and then)
            break
    cobs_ok = at == end

    packets = rows[:, 1:length]
    crc = crc_rows(packets)
    value = np.zeros(count, dtype=np.uint64)
    for byte in range(HEADER_BYTES):        # the header is little-endian
        value |= packets[:, byte].astype(np.uint64) << np.uint64(8 * byte)
    type = _header_field(value, "type")
    seq = _header_field(value, "seq")
    payload = length - 1 - HEADER_BYTES - CRC_BYTES
    code = np.where(~cobs_ok, NakCode.TRUNCATED.value,
                    np.where(crc != 0, NakCode.BAD_CRC.value,
                             np.where(_header_field(value, "length") != payload,
                                      NakCode.BAD_LENGTH.value, 0)))
    return rows, code, type, seq, scalar


@dataclass
class Decoded:
    """What :meth:`BulkDecoder.feed_events` returns.

    ``events`` (``EVENT_DTYPE``) are the events of every EVENTS packet whose payload is a whole
    number of events, in order, and ``event_counts`` the number of events of each of those
    packets. ``items`` is everything else :meth:`FrameDecoder.feed
    <fliss.protocol.FrameDecoder.feed>` would have returned, in order: the other packets
    (an EVENTS packet with a payload of another length among them), and every
    :class:`~fliss.protocol.LinkError`, :class:`~fliss.protocol.SequenceGap` and
    :class:`~fliss.protocol.Resync`.
    """
    events: np.ndarray
    event_counts: np.ndarray
    items: list

    def batches(self):
        """``events`` split into one array (a view) per EVENTS packet."""
        return np.split(self.events, np.cumsum(self.event_counts)[:-1]) \
            if len(self.event_counts) else []


def _payload_words(payload):
    """The events of an EVENTS payload as 64-bit little-endian words."""
    words = np.zeros((len(payload) // EVENT_BYTES, 8), dtype=np.uint8)
    words[:, :EVENT_BYTES] = np.frombuffer(payload, dtype=np.uint8).reshape(-1, EVENT_BYTES)
    return words.view("<u8")[:, 0]


def _is_event_packet(item):
    return isinstance(item, Packet) and item.type == PacketType.EVENTS and \
        len(item.payload) % EVENT_BYTES == 0


class _Frames:
    """The complete frames of one read, decoded: per frame its ``code`` (0 for a packet),
    ``type``, ``seq``, payload length ``size`` and, once sequence numbers are checked, the
    ``expected`` sequence number and the packets ``missing`` before it."""

    def __init__(self, data, buf, starts, lengths, min_group):
        self.data, self.starts, self.lengths = data, starts, lengths
        count = len(starts)
        self.code = np.zeros(count, dtype=np.int64)
        self.type = np.zeros(count, dtype=np.int64)
        self.seq = np.zeros(count, dtype=np.int64)
        self.size = np.zeros(count, dtype=np.int64)
        self.group = np.full(count, -1, dtype=np.int64)     # bulk group, or -1
        self.row = np.zeros(count, dtype=np.int64)
        self.groups = []                                    # (rows, frame indices) per group
        self.scalar = {}                                    # frame index: Packet, for the rest

        self.code[lengths > MAX_ENCODED] = NakCode.OVERSIZE.value
        order = np.argsort(lengths, kind="stable")
        sorted_lengths = lengths[order]
        bounds = np.flatnonzero(np.diff(sorted_lengths)) + 1
        rest = []
        for first, stop in zip(np.r_[0, bounds], np.r_[bounds, count]):
            length = int(sorted_lengths[first])
            frames = order[first:stop]
            if length > MAX_ENCODED:
                continue
            if stop - first < min_group or \
                    not HEADER_BYTES + CRC_BYTES <= length - 1 <= MAX_PACKET:
                rest.append(frames)
                continue
            rows, code, type, seq, scalar = _decode_group(buf, starts[frames], length)
            self.code[frames] = code
            self.type[frames] = type
            self.seq[frames] = seq
            self.size[frames] = length - 1 - HEADER_BYTES - CRC_BYTES
            self.group[frames] = len(self.groups)
            self.row[frames] = np.arange(len(frames))
            self.groups.append((rows, frames))
            rest.append(frames[scalar])
        for index in np.sort(np.concatenate(rest)).tolist() if rest else []:
            start = int(starts[index])
            packet, code = decode_frame(data[start:start + int(lengths[index])])
            self.group[index] = -1
            if packet is None:
                self.code[index] = code.value
            else:
                self.code[index] = 0
                self.scalar[index] = packet
                self.type[index] = packet.type.value if isinstance(packet.type, PacketType) \
                    else packet.type
                self.seq[index] = packet.seq
                self.size[index] = len(packet.payload)

    def check(self, decoder):
        """Check sequence numbers from the decoder's state on, and add everything up in its
        counters."""
        counters = decoder.counters
        self.expected = np.zeros(len(self.code), dtype=np.int64)
        self.missing = np.zeros(len(self.code), dtype=np.int64)
        good = np.flatnonzero(self.code == 0)
        if len(good):
            seq = self.seq[good]
            expected = np.empty_like(seq)
            expected[1:] = (seq[:-1] + 1) % _SEQ_MODULUS
            expected[0] = seq[0] if decoder._expected_seq is None else decoder._expected_seq
            missing = (seq - expected) % _SEQ_MODULUS
            self.expected[good] = expected
            self.missing[good] = missing
            decoder._expected_seq = int(seq[-1] + 1) % _SEQ_MODULUS
            counters.sequence_gaps += int(np.count_nonzero(missing))
            counters.missing_packets += int(missing.sum())
            counters.packets += len(good)
            counters.payload_bytes += int(self.size[good].sum())
        codes, counts = np.unique(self.code[self.code != 0], return_counts=True)
        for code, count in zip(codes.tolist(), counts.tolist()):
            counters.errors[NakCode(code)] += count

    def items(self, indices):
        """Reports and packets of the frames ``indices``, in order; EVENTS packets with whole
        events only if ``self.skip_events`` is False."""
        out = []
        types, naks = {}, {}
        blobs = {}
        code, seq, type, size = self.code, self.seq, self.type, self.size
        missing, expected, group, row = self.missing, self.expected, self.group, self.row
        for index in indices:
            nak = int(code[index])
            if nak:
                if nak not in naks:
                    naks[nak] = NakCode(nak)
                start = int(self.starts[index])
                stop = start + min(int(self.lengths[index]), _KEEP + 1)
                out.append(LinkError(naks[nak], bytes(self.data[start:stop])))
                continue
            if missing[index]:
                out.append(SequenceGap(int(expected[index]), int(seq[index]),
                                       int(missing[index])))
            if self.skip_events and type[index] == _EVENTS and size[index] % EVENT_BYTES == 0:
                continue
            packet = self.scalar.get(index)
            if packet is None:
                number = int(group[index])
                if number not in blobs:
                    blobs[number] = self.groups[number][0].tobytes()
                width = self.groups[number][0].shape[1]
                start = int(row[index]) * width + 1 + HEADER_BYTES
                value = int(type[index])
                if value not in types:
                    types[value] = packet_type(value)
                packet = Packet(types[value], int(seq[index]),
                                blobs[number][start:start + int(size[index])])
            out.append(packet)
        return out

    def events(self, head_events):
        """The events of the EVENTS packets with whole events, after ``head_events`` (payloads
        as bytes); returns ``(events, counts)``."""
        wanted = (self.code == 0) & (self.type == _EVENTS) & (self.size % EVENT_BYTES == 0)
        counts = self.size // EVENT_BYTES
        head_counts = [len(payload) // EVENT_BYTES for payload in head_events]
        first = np.cumsum(np.where(wanted, counts, 0)) - np.where(wanted, counts, 0) + \
            sum(head_counts)
        total = sum(head_counts) + int(counts[wanted].sum())
        # One 64-bit little-endian word per event, its bits above the event ignored by unpack.
        words = np.empty(total, dtype=np.uint64)
        at = 0
        for payload in head_events:
            words[at:at + len(payload) // EVENT_BYTES] = _payload_words(payload)
            at += len(payload) // EVENT_BYTES
        for number, (rows, frames) in enumerate(self.groups):
            take = np.flatnonzero(wanted[frames] & (self.group[frames] == number))
            if not len(take):
                continue
            per_packet = int(counts[frames[0]])
            # Each event read as 8 bytes in place, overlapping the next (the rows are wide
            # enough for the last event's 8th byte).
            width = rows.shape[1]
            block = np.ndarray((len(rows), per_packet), dtype="<u8", buffer=rows,
                               offset=1 + HEADER_BYTES, strides=(width, EVENT_BYTES))
            block = block[take] if len(take) < len(rows) else block
            where = first[frames[take]]
            if np.array_equal(where, where[0] + per_packet * np.arange(len(where))):
                words[where[0]:where[0] + block.size] = block.reshape(-1)
            else:
                words[(where[:, None] + np.arange(per_packet)).reshape(-1)] = block.reshape(-1)
        for index, packet in self.scalar.items():
            if wanted[index]:
                block = _payload_words(packet.payload)
                words[first[index]:first[index] + len(block)] = block
        events = _event.unpack(words)
        return events, np.concatenate([np.array(head_counts, dtype=np.int64), counts[wanted]])


class BulkDecoder(FrameDecoder):
    """A :class:`~fliss.protocol.FrameDecoder` that decodes large reads with numpy.

    :meth:`feed` returns what :meth:`FrameDecoder.feed
    <fliss.protocol.FrameDecoder.feed>` returns, and :attr:`counters` count the same;
    :meth:`feed_events` returns the events of EVENTS packets as one array. Both may be mixed on
    one stream: a frame cut by the end of one read is finished by the next.

    Parameters
    ----------
    synced : bool
        As for :class:`~fliss.protocol.FrameDecoder`.
    min_bytes : int
        Reads shorter than this go to the scalar decoder.
    min_group : int
        Frames of one length are decoded in bulk when a read holds at least this many of them.
    """

    def __init__(self, *, synced=False, min_bytes=BULK_MIN_BYTES, min_group=BULK_MIN_GROUP):
        super().__init__(synced=synced)
        self.min_bytes = int(min_bytes)
        self.min_group = max(1, int(min_group))

    def _decode(self, data):
        """Decode ``data``; returns the items of its first frame (decoded by the scalar decoder,
        as it may have begun in an earlier read) and the :class:`_Frames` after it, or ``None``
        when there are none."""
        if len(data) < self.min_bytes:
            return FrameDecoder.feed(self, data), None
        buf = np.frombuffer(data, dtype=np.uint8)
        delimiters = np.flatnonzero(buf == DELIMITER)
        if len(delimiters) < 2:
            return FrameDecoder.feed(self, data), None
        first, last = int(delimiters[0]), int(delimiters[-1])
        head = FrameDecoder.feed(self, data[:first + 1])
        starts = delimiters[:-1] + 1
        lengths = delimiters[1:] - starts
        present = lengths > 0           # a lone delimiter is an empty frame, ignored
        frames = _Frames(data, buf, starts[present], lengths[present], self.min_group)
        frames.check(self)
        self.counters.bytes += last - first
        FrameDecoder.feed(self, data[last + 1:])        # a frame cut short, kept for later
        return head, frames

    def feed(self, data):
        """Decode ``data`` (bytes-like); returns the list of packets and reports found."""
        data = bytes(data)
        head, frames = self._decode(data)
        if frames is None:
            return head
        frames.skip_events = False
        return head + frames.items(range(len(frames.code)))

    def feed_events(self, data):
        """Decode ``data`` (bytes-like); returns a :class:`Decoded`: the events of the EVENTS
        packets as one array, and everything else in a list."""
        data = bytes(data)
        head, frames = self._decode(data)
        head_events = [item.payload for item in head if _is_event_packet(item)]
        items = [item for item in head if not _is_event_packet(item)]
        if frames is None:
            counts = np.array([len(p) // EVENT_BYTES for p in head_events], dtype=np.int64)
            return Decoded(_event.unpack(_payload_words(b"".join(head_events))), counts, items)
        frames.skip_events = True
        events, counts = frames.events(head_events)
        special = (frames.code != 0) | (frames.missing != 0) | (frames.type != _EVENTS) | \
            (frames.size % EVENT_BYTES != 0)
        items += frames.items(np.flatnonzero(special).tolist())
        return Decoded(events, counts, items)


def decode_stream(data, *, synced=True):
    """Decode a recorded byte stream at once; returns a :class:`Decoded` and the
    :class:`~fliss.protocol.LinkCounters`.

    ``synced`` as for :class:`~fliss.protocol.FrameDecoder`: True when the recording begins
    with a frame. A frame not ended by a delimiter at the end of the recording is not decoded
    (nor counted), as with the streaming decoder.
    """
    decoder = BulkDecoder(synced=synced, min_bytes=0)
    decoded = decoder.feed_events(data)
    return decoded, decoder.counters
