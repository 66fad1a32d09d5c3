"""HISTOGRAM and HISTOGRAM_COMPACT packets: the board's choice between them, and their decoding.

The bit-exact model of :class:`fliss.hdl.packets.histogram.HistogramPacketizer`
(``docs/protocol.md``, "Histogram readout").

A frame of ``bins`` bins (flat index ``pixel << (13 - shift) | bin``) is cut into *windows* of
``window = min(CHUNK_BINS, bins)`` bins, taken in order. For each window the board compares two
payloads: ``F``, the window as a HISTOGRAM chunk (:class:`~fliss.hdl.protocol.HistogramChunk`
and two bytes a bin), and ``C``, the window alone as a HISTOGRAM_COMPACT chunk
(:class:`~fliss.hdl.protocol.HistogramCompact` and the window's tokens, see :func:`tokens`).
The window is *compact* when ``full_readout`` is 0 and ``C < F``; otherwise it is sent as a
HISTOGRAM chunk.

Consecutive compact windows share one HISTOGRAM_COMPACT chunk: a compact window is appended to
the chunk in progress when its tokens, continuing that chunk (the run of empty bins before its
first count includes the trailing empty bins of the chunk so far), still fit in
:data:`~fliss.hdl.protocol.COMPACT_BYTES`; otherwise the chunk in progress is sent and a new one
starts with the window. A full window and the frame's last window end the chunk in progress.
Trailing empty bins of a compact chunk take no token: its ``last_bin`` covers them.

Decoding (:func:`decode_chunk`) gives the counts of either form and refuses every payload the
board cannot have made with :exc:`MalformedChunk`.
"""

from dataclasses import dataclass

import numpy as np

from ..hdl.event import ADDRESS_BITS, TIMESTAMP_BITS
from ..hdl.protocol import (CHUNK_BINS, COMPACT_BYTES, HISTOGRAM_COUNT_BITS, MAX_FRAME_BITS,
                            HistogramChunk, HistogramCompact, PacketType)
from .layout import byte_size, pack, unpack_from, word_dtype
from .packets import HISTOGRAM_TYPES
from .frames import packet_type


__all__ = ["FULL_HEADER_BYTES", "COMPACT_HEADER_BYTES",
           "MalformedChunk", "Chunk", "frame_bins", "tokens", "window_is_compact",
           "encode_histogram", "decode_chunk", "assemble"]


#: The packet types that carry histogram chunks.

#: Bytes of the headers of the two payloads.
FULL_HEADER_BYTES = byte_size(HistogramChunk)
COMPACT_HEADER_BYTES = byte_size(HistogramCompact)

_COUNT_BYTES = HISTOGRAM_COUNT_BITS // 8
_COUNT_DTYPE = word_dtype(HISTOGRAM_COUNT_BITS)
_COUNT_MAX = (1 << HISTOGRAM_COUNT_BITS) - 1
#: Largest token value (a run or a count of 65535) and its length in bytes.
_TOKEN_MAX = (_COUNT_MAX << 1) | 1
_TOKEN_MAX_BYTES = (_TOKEN_MAX.bit_length() + 6) // 7


class MalformedChunk(ValueError):
    """A histogram chunk the board cannot have sent."""


@dataclass(frozen=True)
class Chunk:
    """One decoded chunk: its header fields and ``counts`` (u16) of the flat indices
    ``first_bin …``; ``compact`` tells which packet it came in."""
    frame: int
    first_bin: int
    first_pixel: int
    shift: int
    pixel_bits: int
    last: int
    counts: np.ndarray
    compact: bool

    @property
    def bins(self):
        """Bins of this chunk's frame."""
        return frame_bins(self.shift, self.pixel_bits)


def frame_bins(shift, pixel_bits=0):
    """Bins of a frame of ``2**pixel_bits`` pixels of ``2**(13 - shift)`` bins."""
    return 1 << (pixel_bits + TIMESTAMP_BITS - shift)


def _check_split(shift, pixel_bits, first_pixel):
    # The frame settings a board can send, or MalformedChunk.
    if shift > TIMESTAMP_BITS:
        raise MalformedChunk(f"bin shift {shift} is above {TIMESTAMP_BITS}")
    if pixel_bits > ADDRESS_BITS or first_pixel + (1 << pixel_bits) > 1 << ADDRESS_BITS:
        raise MalformedChunk(f"pixels {first_pixel} … {first_pixel + (1 << pixel_bits) - 1} "
                             f"are beyond the {1 << ADDRESS_BITS} pixel addresses")
    if pixel_bits + TIMESTAMP_BITS - shift > MAX_FRAME_BITS:
        raise MalformedChunk(f"a frame of 2**{pixel_bits} pixels of 2**{TIMESTAMP_BITS - shift} "
                             f"bins is beyond the 2**{MAX_FRAME_BITS} flat indices")


def _leb128(value, out):
    while value >= 0x80:
        out.append(0x80 | (value & 0x7f))
        value >>= 7
    out.append(value)


def tokens(counts, run=0):
    """Tokens of the bins ``counts`` (each at most 65535) after ``run`` empty bins not yet
    described; returns ``(token bytes, empty bins left at the end)``.

    A bin of count ``c > 0`` gives the token ``2 c``, after the token ``2 r + 1`` of the ``r > 0``
    empty bins before it; empty bins at the end take no token yet.
    """
    counts = np.asarray(counts, dtype=np.int64)
    out = bytearray()
    last = -1       # the last bin with a count (only those are visited)
    filled = np.flatnonzero(counts)
    for index, count in zip(filled.tolist(), counts[filled].tolist()):
        run += index - last - 1
        if run:
            _leb128((run << 1) | 1, out)
            run = 0
        _leb128(count << 1, out)
        last = index
    return bytes(out), run + len(counts) - last - 1


class _WindowTokens:
    """The tokens of every window of ``window`` bins of ``counts``, made at once: what
    :func:`tokens` gives for each window alone, in a fraction of the time (a frame has up to
    a thousand windows, most of them nearly empty)."""

    def __init__(self, counts, window):
        self.window = window
        filled = np.flatnonzero(counts)
        windows = filled // window
        first = np.ones(len(filled), bool)
        first[1:] = windows[1:] != windows[:-1]
        gaps = np.diff(filled, prepend=0) - 1
        # The tokens after each window's first run token: a run token before every other count
        # that follows empty bins, then the count's token
        values = np.empty(2 * len(filled), np.int64)
        values[0::2] = (gaps << 1) | 1
        values[1::2] = counts[filled].astype(np.int64) << 1
        kept = np.ones(len(values), bool)
        kept[0::2] = ~first & (gaps > 0)
        values, owner = values[kept], np.repeat(windows, 2)[kept]
        lengths = 1 + (values >= 1 << 7) + (values >= 1 << 14)    # (all below 2**21)
        ends = np.cumsum(lengths)
        data = np.empty(int(ends[-1]) if len(ends) else 0, np.uint8)
        for place in range(3):
            has = lengths > place
            more = lengths > place + 1
            data[(ends - lengths + place)[has]] = \
                ((values[has] >> (7 * place)) & 0x7f) | np.where(more[has], 0x80, 0)
        self.data = data.tobytes()
        # Per window: its first count's offset, its last's, and its tokens' bytes
        numbers = np.arange((len(counts) + window - 1) // window)
        self.begin = np.searchsorted(windows, numbers)
        self.end = np.searchsorted(windows, numbers, side="right")
        self.filled = filled
        starts = np.concatenate(([0], ends))
        self.byte_begin = starts[np.searchsorted(owner, numbers)]
        self.byte_end = starts[np.searchsorted(owner, numbers, side="right")]

    def tokens(self, number, run=0):
        """:func:`tokens` of window ``number`` after ``run`` empty bins."""
        begin, end = self.begin[number], self.end[number]
        if begin == end:
            return b"", run + self.window
        offset = int(self.filled[begin]) - number * self.window
        last = int(self.filled[end - 1]) - number * self.window
        head = bytearray()
        if run + offset:
            _leb128(((run + offset) << 1) | 1, head)
        body = self.data[self.byte_begin[number]:self.byte_end[number]]
        return bytes(head) + body, self.window - 1 - last


def window_is_compact(window_tokens, window_bins, full_readout=False):
    """The board's choice for one window: ``True`` when ``full_readout`` is off and the window
    alone as a compact chunk (``window_tokens`` bytes of tokens) is a shorter payload than as
    a HISTOGRAM chunk."""
    return not full_readout and COMPACT_HEADER_BYTES + window_tokens < \
        FULL_HEADER_BYTES + _COUNT_BYTES * window_bins


def encode_histogram(counts, *, frame, shift, pixel_bits=0, first_pixel=0, full_readout=False):
    """The packets of one frame as the board sends them: a list of ``(PacketType, payload)``.

    ``counts`` holds the frame's ``frame_bins(shift, pixel_bits)`` bins in flat index order
    (values above 65535 are sent as 65535, as the readout saturates).
    """
    counts = np.minimum(np.asarray(counts, dtype=np.int64), _COUNT_MAX)
    bins = frame_bins(shift, pixel_bits)
    if counts.shape != (bins,):
        raise ValueError(f"A frame of bin shift {shift} and {1 << pixel_bits} pixels has {bins} "
                         f"bins, not {counts.shape}")
    _check_split(shift, pixel_bits, first_pixel)
    split = dict(frame=frame & 0xffffffff, first_pixel=first_pixel, shift=shift,
                 pixel_bits=pixel_bits)
    window = min(CHUNK_BINS, bins)
    packets = []
    compact = None      # the compact chunk in progress: [first_bin, last_bin, tokens, run]

    def close(last):
        first_bin, last_bin, data, _ = compact
        packets.append((PacketType.HISTOGRAM_COMPACT,
                        pack(HistogramCompact, **split, first_bin=first_bin, last_bin=last_bin,
                             last=last) + data))

    pieces = _WindowTokens(counts, window)
    for number, start in enumerate(range(0, bins, window)):
        part = counts[start:start + window]
        end = start + window - 1
        last = int(end == bins - 1)
        fresh, fresh_run = pieces.tokens(number)
        if window_is_compact(len(fresh), window, full_readout):
            if compact is not None:
                carried, carried_run = pieces.tokens(number, compact[3])
                if len(compact[2]) + len(carried) <= COMPACT_BYTES:
                    compact = [compact[0], end, compact[2] + carried, carried_run]
                else:
                    close(0)
                    compact = [start, end, fresh, fresh_run]
            else:
                compact = [start, end, fresh, fresh_run]
            if last:
                close(1)
        else:
            if compact is not None:
                close(0)
                compact = None
            packets.append((PacketType.HISTOGRAM,
                            pack(HistogramChunk, **split, first_bin=start, last=last) +
                            part.astype(_COUNT_DTYPE).tobytes()))
    return packets


def _decode_tokens(data, span):
    # Counts of `span` bins from compact tokens (vectorised), or MalformedChunk.
    raw = np.frombuffer(data, dtype=np.uint8)
    counts = np.zeros(span, dtype=np.uint16)
    if not len(raw):
        return counts
    if raw[-1] & 0x80:
        raise MalformedChunk("the last token is cut short")
    ends = np.flatnonzero(raw < 0x80)
    starts = np.concatenate(([0], ends[:-1] + 1))
    lengths = ends - starts + 1
    if lengths.max() > _TOKEN_MAX_BYTES:
        raise MalformedChunk(f"a token is longer than {_TOKEN_MAX_BYTES} bytes")
    if np.any((lengths > 1) & (raw[ends] == 0)):
        raise MalformedChunk("a token has a needless zero byte")
    token = np.repeat(np.arange(len(ends)), lengths)
    place = np.arange(len(raw)) - starts[token]
    values = np.zeros(len(ends), dtype=np.int64)
    np.add.at(values, token, (raw & 0x7f).astype(np.int64) << (7 * place))
    if values.max() > _TOKEN_MAX:
        raise MalformedChunk(f"a token is above {_TOKEN_MAX}")
    if np.any(values <= 1):
        raise MalformedChunk("a token of count 0 or of 0 empty bins")
    run = (values & 1).astype(bool)
    steps = np.where(run, values >> 1, 1)
    ends_at = np.cumsum(steps)
    if ends_at[-1] > span:
        raise MalformedChunk(f"the tokens describe {int(ends_at[-1])} bins, more than the "
                             f"chunk's {span}")
    counts[(ends_at - 1)[~run]] = values[~run] >> 1
    return counts


def decode_chunk(type, payload):
    """The :class:`Chunk` of a HISTOGRAM or HISTOGRAM_COMPACT ``payload`` (``type`` a
    :class:`~fliss.hdl.protocol.PacketType`); raises :exc:`MalformedChunk` for one that does not
    fit its frame, cut short or longer than the board makes, with bad tokens."""
    payload = bytes(payload)
    compact = type == PacketType.HISTOGRAM_COMPACT
    if not compact and type != PacketType.HISTOGRAM:
        raise MalformedChunk(f"packet type {type!r} carries no histogram")
    header = COMPACT_HEADER_BYTES if compact else FULL_HEADER_BYTES
    if len(payload) < header:
        raise MalformedChunk(f"payload of {len(payload)} bytes is shorter than its "
                             f"{header}-byte header")
    fields = unpack_from(HistogramCompact if compact else HistogramChunk, payload)
    _check_split(fields["shift"], fields["pixel_bits"], fields["first_pixel"])
    bins = frame_bins(fields["shift"], fields["pixel_bits"])
    first = fields["first_bin"]
    body = payload[header:]
    if compact:
        last_bin = fields["last_bin"]
        if not first <= last_bin < bins:
            raise MalformedChunk(f"bins {first} … {last_bin} are not in a frame of {bins} bins")
        if len(body) > COMPACT_BYTES:
            raise MalformedChunk(f"{len(body)} bytes of tokens, more than {COMPACT_BYTES}")
        counts = _decode_tokens(body, last_bin - first + 1)
    else:
        if len(body) % _COUNT_BYTES:
            raise MalformedChunk(f"{len(body)} bytes of counts are not whole u16 counts")
        counts = np.frombuffer(body, dtype=_COUNT_DTYPE)
        if not counts.size or first + counts.size > bins or counts.size > CHUNK_BINS:
            raise MalformedChunk(f"{counts.size} counts from bin {first} are not in a frame of "
                                 f"{bins} bins")
    return Chunk(fields["frame"], first, fields["first_pixel"], fields["shift"],
                 fields["pixel_bits"], fields["last"], counts, compact)


def assemble(packets):
    """Frames from ``(type, payload)`` histogram packets (other types are skipped), for tests
    and models: ``{frame: (Chunk of the frame's settings, counts, whole)}``; ``whole`` when every
    bin arrived and the frame's last chunk with it. Malformed chunks raise."""
    frames = {}
    for type, payload in packets:
        if packet_type(type) not in HISTOGRAM_TYPES:
            continue
        chunk = decode_chunk(packet_type(type), payload)
        if chunk.frame not in frames:
            frames[chunk.frame] = [chunk, np.zeros(chunk.bins, np.int64),
                                   np.zeros(chunk.bins, bool), False]
        entry = frames[chunk.frame]
        entry[1][chunk.first_bin:chunk.first_bin + len(chunk.counts)] = chunk.counts
        entry[2][chunk.first_bin:chunk.first_bin + len(chunk.counts)] = True
        entry[3] |= bool(chunk.last)
    return {frame: (chunk, counts, bool(filled.all()) and ended)
            for frame, (chunk, counts, filled, ended) in frames.items()}

