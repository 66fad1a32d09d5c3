"""cocotb testbench of the depth engine (:class:`fliss.hdl.depth.engine.DepthEngine`) against its
model (:mod:`fliss.sim.models.depth`), bit for bit.

Random frames (every split of 1 to 64 pixels by 1 to 8192 bins that fits the 13-bit index:
Gaussian peaks on a background, flat, empty, saturated, peaks at the edges) go in as a histogram
readout would present them, with random gaps; packets come out against random back pressure.
Each DEPTH packet must be the model's payload for its frame, byte for byte.
``FLISS_TB_DEPTH_FRAMES`` frames (40 by default), seed ``FLISS_TB_DEPTH_SEED``.
"""

import os
import random

import cocotb
import numpy as np
from amaranth.lib import data
from cocotb.clock import Clock
from cocotb.triggers import ClockCycles, FallingEdge

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.event import TIMESTAMP_BITS
from ...hdl.link.framing import PacketBeat
from ...hdl.histogram.layout import readout_layout
from ...hdl.protocol import PacketType
from ...hdl.registers import DEPTH
from ..models.depth import depth_frame
from ...protocol.depth import depth_payload, unpack_depth


FRAMES = int(os.environ.get("FLISS_TB_DEPTH_FRAMES", 40))
SEED = int(os.environ.get("FLISS_TB_DEPTH_SEED", 1))
CLOCK_PERIOD_PS = round(1e12 / DEFAULT_CLOCK_HZ)

_READOUT = data.Layout.cast(readout_layout(TIMESTAMP_BITS))   # (the engine's default index)
_BEAT = data.Layout.cast(PacketBeat)
_HEADER = data.Layout.cast(_BEAT["header"].shape)
_SETTINGS = data.Layout.cast(DEPTH.layout())


def _field(value, layout, name):
    field = layout[name]
    return (value >> field.offset) & ((1 << field.width) - 1)


def random_frame(rng):
    """One frame: counts (P, N) and its settings."""
    shift = rng.randint(3, 13)
    n = TIMESTAMP_BITS - shift
    pixel_bits = rng.randint(0, min(6, 11 - n))     # at most 2048 bins: short frames
    pixels, bins = 1 << pixel_bits, 1 << n
    np_rng = np.random.default_rng(rng.getrandbits(32))
    kind = rng.random()
    if kind < 0.7:
        x = np.arange(bins) + 0.5
        centres = np_rng.uniform(-1, bins + 1, pixels)
        sigma = rng.uniform(0.3, 4)
        rate = rng.uniform(0, 30) + rng.uniform(1, 3000) * np.exp(
            -0.5 * ((x[None] - centres[:, None]) / sigma) ** 2)
        counts = np.minimum(np_rng.poisson(rate), 65535)
    elif kind < 0.8:
        counts = np.full((pixels, bins), rng.choice([0, 1, 7, 65535]))
    elif kind < 0.9:
        counts = np_rng.integers(0, 65536, (pixels, bins))
    else:
        counts = np_rng.integers(0, 4, (pixels, bins))
        counts[:, rng.choice([0, bins - 1])] = 65535
    return dict(counts=counts, shift=shift, pixel_bits=pixel_bits,
                first_pixel=rng.randint(0, 64 - pixels), filter=rng.randint(1, 16),
                threshold=rng.choice([0, rng.randrange(200), rng.randrange(1 << 16)]))


def expected_payload(frame, number):
    records = depth_frame(frame["counts"], shift=frame["shift"], filter=frame["filter"],
                          threshold=frame["threshold"])
    return depth_payload(records, frame=number, first_pixel=frame["first_pixel"],
                         pixel_bits=frame["pixel_bits"], shift=frame["shift"],
                         filter=frame["filter"], threshold=frame["threshold"])


class TB:
    """Clock, reset, the readout driver, the packet monitor and the in-order checker."""

    def __init__(self, dut, rng):
        self.dut = dut
        self.rng = rng
        self.packets = []
        self.compared = 0
        self.mismatches = []

    async def reset(self):
        dut = self.dut
        Clock(dut.clk, CLOCK_PERIOD_PS, unit="ps", impl="gpi").start()
        dut.rst.value = 1
        dut.readout__valid.value = 0
        dut.packets__ready.value = 0
        await ClockCycles(dut.clk, 3)
        dut.rst.value = 0
        await FallingEdge(dut.clk)

    def _settings(self, frame):
        dut = self.dut
        dut.shift.value = frame["shift"]
        dut.pixel_bits.value = frame["pixel_bits"]
        dut.first_pixel.value = frame["first_pixel"]
        dut.settings.value = (frame["filter"] << _SETTINGS["filter"].offset) | \
            (frame["threshold"] << _SETTINGS["threshold"].offset)

    def _monitor(self, ready):
        # Called at a falling edge, with ``ready`` as driven for the next rising edge.
        dut = self.dut
        if not (ready and int(dut.packets__valid.value)):
            return
        beat = int(dut.packets__payload.value)
        if _field(beat, _BEAT, "first"):
            header = _field(beat, _BEAT, "header")
            self._packet = [_field(header, _HEADER, "type"), _field(header, _HEADER, "length"),
                            bytearray()]
        else:
            self._packet[2].append(_field(beat, _BEAT, "data"))
        if _field(beat, _BEAT, "last"):
            self.packets.append(tuple(self._packet))

    async def run(self, frames):
        """Drive every frame's bins, monitor the packets until one per frame has come."""
        dut, rng = self.dut, self.rng
        bins = [(k, frame, index, int(count)) for k, frame in enumerate(frames)
                for index, count in enumerate(np.asarray(frame["counts"]).reshape(-1))]
        position, quiet = 0, 0
        while len(self.packets) < len(frames):
            ready = rng.random() < 0.8
            dut.packets__ready.value = int(ready)
            self._monitor(ready)
            if position < len(bins):
                k, frame, index, count = bins[position]
                if index == 0:
                    self._settings(frame)
                valid = rng.random() < 0.8
                dut.readout__valid.value = int(valid)
                last = int(index == frame["counts"].size - 1)
                dut.readout__payload.value = (index << _READOUT["index"].offset) | \
                    (count << _READOUT["count"].offset) | (last << _READOUT["last"].offset)
                if valid and int(dut.readout__ready.value):
                    position += 1
            else:
                dut.readout__valid.value = 0
                quiet += 1
                assert quiet < 200_000, "no packet for 200 000 cycles"
            await FallingEdge(dut.clk)
        dut.readout__valid.value = 0

    def check(self, frames):
        for number, (frame, (type_, length, payload)) in enumerate(zip(frames, self.packets)):
            expected = expected_payload(frame, number)
            self.compared += 1
            if type_ != PacketType.DEPTH.value or length != len(payload) or \
                    bytes(payload) != expected:
                self.mismatches.append((number, unpack_depth(bytes(payload)),
                                        unpack_depth(expected)))


@cocotb.test()
async def test_depth_frames(dut):
    """Random frames: every DEPTH packet equals the model's, byte for byte."""
    rng = random.Random(SEED)
    frames = [random_frame(rng) for _ in range(FRAMES)]
    tb = TB(dut, rng)
    await tb.reset()
    await tb.run(frames)
    tb.check(frames)
    assert tb.mismatches == [], tb.mismatches[:2]
    assert tb.compared == FRAMES > 0
    assert int(dut.frames.value) == FRAMES
    dut._log.info("%d depth frames (%d pixels) equal the model's", tb.compared,
                  sum(1 << frame["pixel_bits"] for frame in frames))
