"""cocotb test of the histogram readout's packets (:class:`fliss.sim.benches.histogram_link_top.
HistogramLinkTop`) against the model, on the wire, byte for byte.

Sparse, dense, empty and saturated frames of several bank splits, one with ``full_readout``,
and windows on both sides of the choice rule go in as a readout stream (with gaps); the frames
that come out must be exactly those of :func:`fliss.protocol.histograms.encode_histogram`,
numbered from 0 by the arbiter, and decode to the frames' counts. The wire bytes are written to
``FLISS_TB_PACKETIZER_OUT`` (if set) for the host's decoder to check too.
"""

import os
import random

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.triggers import ClockCycles, FallingEdge

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ... import protocol
from .histogram_link_top import INDEX_BITS
from ...protocol.histograms import assemble, encode_histogram, frame_bins


CLOCK_PERIOD_PS = round(1e12 / DEFAULT_CLOCK_HZ)
#: Cycles without output after the last bin that end the test.
IDLE_CYCLES = 3000


def readout_frames(seed=17):
    """The frames of the test: ``(counts, settings)``, settings as the packetizer takes them."""
    rng = np.random.default_rng(seed)

    def settings(shift, pixel_bits=0, first_pixel=0, full_readout=0):
        return dict(shift=shift, pixel_bits=pixel_bits, first_pixel=first_pixel,
                    full_readout=full_readout)

    def sparse(bins, events, top=64):
        counts = np.zeros(bins, np.int64)
        np.add.at(counts, rng.integers(0, bins, events), rng.integers(1, top, events))
        return np.minimum(counts, 65535)

    paper = sparse(8192, 150)
    paper[520:600] += rng.poisson(20, 80)           # a peak, as the victim's echo
    boundary = [100] * 125 + [1] * 3 + [100] * 126 + [1] * 2   # 253 then 254 token bytes
    mixed = sparse(1024, 60, 1 << 16)
    mixed[256:384] = rng.integers(1, 1 << 16, 128)  # one dense window: full
    return [
        (paper, settings(0)),
        (np.zeros(8192, np.int64), settings(0)),
        (sparse(256, 20), settings(7, 2, 60)),
        (rng.integers(0, 1 << 16, 256), settings(5)),
        (np.full(256, 65535), settings(5)),
        (mixed, settings(6, 3, 8)),
        (mixed, settings(6, 3, 8, full_readout=1)),
        (np.array(boundary), settings(5)),
        (np.array([5]), settings(13)),
        (sparse(frame_bins(10, 6), 300, 9000), settings(10, 6)),
    ]


def expected_wire(frames):
    """The frames on the wire, as the model and the codec make them, numbered from 0."""
    encoder = protocol.PacketEncoder()
    wire = bytearray()
    for number, (counts, settings) in enumerate(frames):
        for type, payload in encode_histogram(counts, frame=number, **settings):
            wire += encoder.frame(type, payload)
    return bytes(wire)


@cocotb.test()
async def test_packets_equal_the_model(dut):
    """Every byte on the wire equals the model's; the packets decode to the frames."""
    Clock(dut.clk, CLOCK_PERIOD_PS, unit="ps", impl="gpi").start()
    rng = random.Random(3)
    frames = readout_frames()
    beats = [(index | int(count) << INDEX_BITS | (index == len(counts) - 1) << (2 * INDEX_BITS),
              settings if index == 0 else None)
             for counts, settings in frames for index, count in enumerate(counts)]
    dut.rst.value = 1
    dut.readout__valid.value = 0
    dut.tx__ready.value = 0
    await ClockCycles(dut.clk, 3)
    dut.rst.value = 0

    out = bytearray()
    position, offered, taken, idle = 0, False, False, 0
    while idle < IDLE_CYCLES:
        await FallingEdge(dut.clk)
        # Readout: a beat taken at the last rising edge makes way for the next one (or a gap).
        if taken:
            position += 1
            offered = False
        if not offered:
            offered = position < len(beats) and rng.random() < 0.8
            if offered:
                payload, settings = beats[position]
                for name, value in (settings or {}).items():
                    getattr(dut, name).value = value
                dut.readout__payload.value = payload
            dut.readout__valid.value = int(offered)
        # (the readout's ready depends on the packetizer's state only, not on this cycle's beat)
        taken = offered and bool(int(dut.readout__ready.value))
        # Wire: bytes taken at random.
        ready = rng.random() < 0.9
        dut.tx__ready.value = int(ready)
        if ready and int(dut.tx__valid.value):
            out.append(int(dut.tx__payload.value))
            idle = 0
        elif position >= len(beats):
            idle += 1

    want = expected_wire(frames)
    path = os.environ.get("FLISS_TB_PACKETIZER_OUT")
    if path:
        with open(path, "wb") as file:
            file.write(bytes(out))
    dut._log.info("%d frames, %d bins: %d bytes on the wire, model %d", len(frames),
                  len(beats), len(out), len(want))
    assert len(out) == len(want)
    assert bytes(out) == want
    decoder = protocol.FrameDecoder(synced=True)
    packets = [(item.type, item.payload) for item in decoder.feed(out)]
    assert decoder.counters.dropped_frames == 0 and decoder.counters.sequence_gaps == 0
    decoded = assemble(packets)
    for number, (counts, _) in enumerate(frames):
        assert decoded[number][2] and np.array_equal(decoded[number][1], counts), number
