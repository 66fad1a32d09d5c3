"""The histogram chunk model: tokens worked out by hand, the board's choice, decoding of both
forms, refusal of every malformed compact chunk, and the host's assembly of both."""

import re

import numpy as np
import pytest

from fliss.hdl.protocol import PacketType, HistogramChunk, HistogramCompact
from fliss.host.stream import HistogramFrame, StreamAssembler
from fliss.protocol.frames import Packet
from fliss.protocol.layout import pack
from fliss.protocol.histograms import (MalformedChunk, _WindowTokens, assemble, decode_chunk,
                                       encode_histogram, frame_bins, tokens)


COMPACT = PacketType.HISTOGRAM_COMPACT
FULL = PacketType.HISTOGRAM


def test_tokens_by_hand():
    # 2 empty bins: 2*2+1 = 5; count 3: 6; count 64: 128 = 0x80 0x01; 200 empty bins:
    # 401 = 0x191 -> 0x91 0x03; count 65535: 131070 = 0x1fffe -> 0xfe 0xff 0x07; two empty
    # bins at the end take no token.
    counts = [0, 0, 3, 64] + [0] * 200 + [65535, 0, 0]
    assert tokens(counts) == (bytes([5, 6, 0x80, 0x01, 0x91, 0x03, 0xfe, 0xff, 0x07]), 2)
    # A run carried in from before joins the first run: 4 + 2 empty bins = 13.
    assert tokens(counts, 4)[0][:1] == bytes([13])


@pytest.mark.parametrize("window", [8, 64, 1024])
def test_a_frames_windows_tokenised_at_once_are_each_windows_tokens(window):
    # The encoder's tokens of every window at once, against tokens() of each window alone
    # (worked out by hand above), after runs carried in of each length class of a token
    rng = np.random.default_rng(window)
    for density in (0.0, 0.002, 0.05, 0.5, 1.0):
        counts = np.where(rng.random(8 * window) < density,
                          rng.choice([1, 63, 64, 8191, 8192, 65535], 8 * window), 0)
        pieces = _WindowTokens(counts, window)
        for number in range(8):
            part = counts[number * window:(number + 1) * window]
            for run in (0, 1, 63, 64, 8192):
                assert pieces.tokens(number, run) == tokens(part, run)


def test_empty_frame_is_one_short_chunk():
    packets = encode_histogram(np.zeros(8192), frame=7, shift=0)
    assert packets == [(COMPACT, pack(HistogramCompact, frame=7, first_bin=0, last_bin=8191,
                                      last=1))]


def test_full_readout_sends_every_window_full():
    counts = np.zeros(256, np.int64)
    counts[3] = 2
    packets = encode_histogram(counts, frame=1, shift=5, pixel_bits=0, full_readout=True)
    assert [type for type, _ in packets] == [FULL, FULL]
    assert packets[0][1] == pack(HistogramChunk, frame=1, first_bin=0, shift=5) + \
        bytes([0] * 6 + [2, 0] + [0] * 248)


@pytest.mark.parametrize("shift,pixel_bits,first_pixel", [(0, 0, 0), (3, 3, 56), (8, 6, 0),
                                                         (13, 0, 63), (10, 1, 5)])
def test_both_forms_decode_to_the_frame(shift, pixel_bits, first_pixel):
    rng = np.random.default_rng(shift)
    bins = frame_bins(shift, pixel_bits)
    for density in (0, 0.01, 0.3, 1):
        counts = np.where(rng.random(bins) < density, rng.integers(1, 1 << 16, bins), 0)
        for full in (False, True):
            packets = encode_histogram(counts, frame=2, shift=shift, pixel_bits=pixel_bits,
                                       first_pixel=first_pixel, full_readout=full)
            chunk, got, whole = assemble(packets)[2]
            assert whole and np.array_equal(got, counts)
            assert (chunk.shift, chunk.pixel_bits, chunk.first_pixel) == \
                (shift, pixel_bits, first_pixel)
            if full:
                assert all(type == FULL for type, _ in packets)


def _compact(tokens, first=0, last=255, shift=5, **fields):
    return pack(HistogramCompact, frame=0, first_bin=first, last_bin=last, shift=shift,
                **fields) + bytes(tokens)


@pytest.mark.parametrize("payload,message", [
    (_compact([5, 6])[:9], "shorter than its 10-byte header"),
    (_compact([0x80]), "cut short"),
    (_compact([0x80, 0x80, 0x80, 0x01]), "longer than 3 bytes"),
    (_compact([0x86, 0x00]), "needless zero byte"),
    (_compact([0x80, 0x80, 0x08]), "above 131071"),
    (_compact([0]), "count 0"),
    (_compact([1]), "0 empty bins"),
    (_compact([0x81, 0x04, 2]), "describe 257 bins, more than the chunk's 256"),
    (_compact([2], first=4, last=3), "bins 4 … 3"),
    (_compact([2], last=256), "bins 0 … 256 are not in a frame of 256"),
    (_compact([2] * 255), "255 bytes of tokens, more than 254"),
    (_compact([], shift=14), "bin shift 14 is above 13"),
    (_compact([], pixel_bits=2, first_pixel=61), "beyond the 64 pixel addresses"),
    (pack(HistogramCompact, shift=0, pixel_bits=4, last_bin=0), "beyond the 2**16"),
])
def test_malformed_compact_chunks_are_refused(payload, message):
    with pytest.raises(MalformedChunk, match=re.escape(message)):
        decode_chunk(COMPACT, payload)


def test_malformed_full_chunks_are_refused():
    header = pack(HistogramChunk, frame=0, first_bin=250, shift=5)
    with pytest.raises(MalformedChunk, match="not whole u16 counts"):
        decode_chunk(FULL, header + bytes(3))
    with pytest.raises(MalformedChunk, match="8 counts from bin 250 are not in a frame of 256"):
        decode_chunk(FULL, header + bytes(16))


def test_assembler_takes_both_forms_and_counts_what_is_malformed():
    rng = np.random.default_rng(3)
    counts = np.zeros(1 << 10, np.int64)         # 4 pixels of 256 bins
    counts[rng.integers(0, 1 << 10, 40)] = rng.integers(1, 70, 40)
    counts[512:640] = rng.integers(100, 9000, 128)   # one dense window: a full chunk
    packets = encode_histogram(counts, frame=4, shift=5, pixel_bits=2, first_pixel=8)
    assert {type for type, _ in packets} == {FULL, COMPACT}
    assembler = StreamAssembler()
    bad = pack(HistogramCompact, frame=4, first_bin=0, last_bin=10, shift=5, pixel_bits=2) + \
        bytes([0x81, 0x01])                      # 64 empty bins in a chunk of 11
    out = assembler.add(Packet(COMPACT, 0, bad), 0.0)
    for seq, (type, payload) in enumerate(packets):
        out += assembler.add(Packet(type, seq + 1, payload), 1.0)
    assert assembler.counters.malformed == 1
    [frame] = out
    assert isinstance(frame, HistogramFrame) and frame.complete
    assert (frame.frame, frame.shift, frame.pixel_bits, frame.first_pixel) == (4, 5, 2, 8)
    assert np.array_equal(frame.counts, counts)
    assert np.array_equal(frame.image[2, :128], counts[512:640])
    assert frame.image.shape == (4, 256)
