"""cocotb testbench of :class:`fliss.hdl.top.FlissTop`, driven only through its pins.

A :class:`TopTB` owns the clock, a UART driver and monitor speaking the protocol with the host
codec (:mod:`fliss.protocol`), and a sensor model that answers the laser's TDC starts with
photon events on the timestamp bus, in closed loop. The expected replies come from the command
processor's model (:mod:`fliss.sim.models.command`); histograms and raw events from the events the
sensor model produced.

The baud rate is given to the design and to this testbench by ``FLISS_TB_BAUD``; the register
maxima of a smaller build (:meth:`fliss.hdl.top.FlissTop.register_maxima`) by
``FLISS_TB_MAXIMA``, as JSON; its histogram bank (:attr:`fliss.hdl.top.FlissTop.bank_bits`) by
``FLISS_TB_BANK_BITS``, and the cycles its histogram takes to clear its banks after reset by
``FLISS_TB_INIT_CYCLES``.
"""

import json
import os
import random

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.simtime import get_sim_time
from cocotb.triggers import ClockCycles, ReadOnly, RisingEdge, Timer, with_timeout

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.protocol import (PacketType, MAX_ENCODED, Nak, ReadRequest, Status, STATUS_FIELDS,
                             LINK_COUNTERS, registers_layout)
from ...hdl.registers import BY_NAME, REGISTERS, AcquisitionMode
from ...hdl.delay.settings import BANK_BITS
from ... import protocol
from ..models.command import CommandModel
from ...protocol.events import EVENT_DTYPE
from ...protocol.histograms import assemble, decode_chunk
from ...protocol.packets import HISTOGRAM_TYPES
from .uart_bfm import UartSink, UartSource


BAUD = int(os.environ.get("FLISS_TB_BAUD", 12_000_000))
FUZZ_FRAMES = int(os.environ.get("FLISS_TB_FUZZ_FRAMES", 10_000))
MAXIMA = json.loads(os.environ.get("FLISS_TB_MAXIMA", "{}"))
BANK_BITS = int(os.environ.get("FLISS_TB_BANK_BITS", BANK_BITS))
#: Cycles after reset before the histogram can start a frame (single-port banks are cleared).
INIT_CYCLES = int(os.environ.get("FLISS_TB_INIT_CYCLES", 0))
#: The design's clock, in Hz (a board build's: its netlist runs at the board's clock).
CLOCK_HZ = float(os.environ.get("FLISS_TB_CLOCK_HZ", DEFAULT_CLOCK_HZ))
CLOCK_HZ = int(CLOCK_HZ) if CLOCK_HZ.is_integer() else CLOCK_HZ
CLOCK_PERIOD_PS = round(1e12 / CLOCK_HZ)


def read_payload(address, count):
    """Payload of a READ of ``count`` registers from ``address``."""
    return protocol.pack(ReadRequest, address=address, count=count)


def write_payload(address, value):
    """Payload of a WRITE of ``value`` to the register at ``address``."""
    return protocol.pack(registers_layout(1), address=address, values=[value])


class TopTB:
    def __init__(self, dut):
        self.dut = dut
        self.encoder = protocol.PacketEncoder()
        self.decoder = protocol.FrameDecoder(synced=True)
        self.model = CommandModel(CLOCK_HZ, BAUD, maxima=MAXIMA, keyed_source=True,
                                  bank_bits=BANK_BITS)
        self.packets = []
        self.link_reports = []
        self.sensor_events = []
        self._consumed = 0

    async def start(self):
        dut = self.dut
        Clock(dut.clk, CLOCK_PERIOD_PS, unit="ps", impl="gpi").start()
        for name in ("sensor_valid", "sensor_timestamp", "sensor_address", "sensor_collision",
                     "photon_hit"):
            getattr(dut, name).value = 0
        self.source = UartSource(dut.uart_rx, BAUD)
        dut.rst.value = 1
        await ClockCycles(dut.clk, 4)
        dut.rst.value = 0
        await ClockCycles(dut.clk, 4)
        self.sink = UartSink(dut.uart_tx, BAUD)
        await ClockCycles(dut.clk, INIT_CYCLES)
        self.pulses = 0   # TDC starts since reset: each test starts acquisition once
        cocotb.start_soon(self._count_pulses())

    async def _count_pulses(self):
        while True:
            await RisingEdge(self.dut.tdc_start)
            self.pulses += 1

    def _drain(self):
        data = bytes(self.sink.received[self._consumed:])
        self._consumed = len(self.sink.received)
        for item in self.decoder.feed(data):
            if isinstance(item, protocol.Packet):
                self.packets.append(item)
            else:
                self.link_reports.append(item)

    async def next_packet(self, *, timeout_us=2000, types=None):
        """The next packet from the board (of one of ``types``, skipping data packets)."""
        deadline = get_sim_time("us") + timeout_us
        while True:
            self._drain()
            while self.packets:
                packet = self.packets.pop(0)
                if types is None or packet.type in types:
                    return packet
                self.data_packets.append(packet)
            if get_sim_time("us") > deadline:
                raise AssertionError("the board did not answer")
            self.sink.event.clear()
            try:
                await with_timeout(self.sink.event.wait(), 50, "us")
            except Exception:
                pass

    data_packets = []

    async def command(self, type, payload=b"", *, check=True):
        """Send a command; return the reply, checked against the model when ``check``."""
        seq = self.encoder.seq
        await self.source.send(self.encoder.frame(type, payload))
        reply = await self.next_packet(types={PacketType.ACK, PacketType.NAK, PacketType.IDENTITY,
                                              PacketType.REGISTERS, PacketType.STATUS})
        if check:
            want_type, want_payload = self.model.command(
                type.value if isinstance(type, PacketType) else type, seq, payload,
                status=self.status_hint(reply))
            assert (reply.type, reply.payload) == (want_type, want_payload), \
                (type, payload, reply, want_type, want_payload)
        return reply

    def status_hint(self, reply):
        # Counters the model cannot know come from the board's own reply.
        if reply.type != PacketType.STATUS:
            return None
        return protocol.unpack(Status, reply.payload)

    async def write(self, **values):
        for name, value in values.items():
            reply = await self.command(PacketType.WRITE,
                                       write_payload(BY_NAME[name].address, value))
            assert reply.type == PacketType.ACK, (name, value, reply)

    async def status(self):
        reply = await self.command(PacketType.GET_STATUS)
        return self.status_hint(reply)

    # Sensor model: after each TDC start, maybe one photon event on the bus.

    def start_sensor(self, rng, probability, *, max_code=8191, addresses=60):
        """Events after TDC starts, of pixel addresses ``0 … addresses - 1``."""
        self._sensor = cocotb.start_soon(self._sensor_loop(rng, probability, max_code,
                                                           addresses))

    def stop_sensor(self):
        self._sensor.cancel()

    async def _sensor_loop(self, rng, probability, max_code, addresses):
        dut = self.dut
        while True:
            await RisingEdge(dut.tdc_start)
            await ReadOnly()
            pulse = self.pulses - 1
            await RisingEdge(dut.clk)
            if rng.random() >= probability:
                continue
            code = rng.randrange(0, max_code + 1)
            address = rng.randrange(0, addresses)
            collision = int(rng.random() < 0.1)
            # The sensor's conversion ends after its 409.6 ns range: present the event then.
            await ClockCycles(dut.clk, 34)
            dut.sensor_timestamp.value = code
            dut.sensor_address.value = address
            dut.sensor_collision.value = collision
            await ClockCycles(dut.clk, 1)
            dut.sensor_valid.value = 1
            await ClockCycles(dut.clk, 2)
            dut.sensor_valid.value = 0
            await ClockCycles(dut.clk, 4)
            self.sensor_events.append((code, address, collision, pulse))


@cocotb.test()
async def test_identify_and_registers(dut):
    """Identity, then every register written and read back, with refusals, against the model."""
    tb = TopTB(dut)
    await tb.start()
    reply = await tb.command(PacketType.PING)
    assert reply.type == PacketType.ACK
    await tb.command(PacketType.IDENTIFY)
    await tb.command(PacketType.READ, read_payload(0, len(REGISTERS)))
    rng = random.Random(1)
    for register in REGISTERS:
        values = [register.minimum, register.maximum, register.maximum + 1,
                  rng.randint(register.minimum, register.maximum)]
        if register.name in MAXIMA:     # a smaller build's own maximum, and one above it
            values += [MAXIMA[register.name], MAXIMA[register.name] + 1]
        for value in values:
            if value < (1 << 32):
                await tb.command(PacketType.WRITE, write_payload(register.address, value))
    await tb.command(PacketType.READ, read_payload(0, len(REGISTERS)))
    await tb.command(PacketType.GET_STATUS)
    assert not tb.link_reports


@cocotb.test()
async def test_fuzz(dut):
    """Random and mutated frames: each gets a NAK with its reason or its proper reply, every
    error is counted, the link resynchronises and no refused setting is applied."""
    tb = TopTB(dut)
    await tb.start()
    rng = random.Random(0xF022)
    valid = [
        (PacketType.PING, b""), (PacketType.IDENTIFY, b""), (PacketType.GET_STATUS, b""),
        (PacketType.READ, read_payload(2, 4)),
        (PacketType.WRITE, write_payload(BY_NAME["length"].address, 40)),
        (PacketType.WRITE, write_payload(BY_NAME["mask_width"].address, 17)),
        (PacketType.WRITE, write_payload(BY_NAME["period"].address, 1)),
        (PacketType.WRITE, write_payload(BY_NAME["seed"].address, 0)),
        (PacketType.WRITE, write_payload(BY_NAME["pulse_width"].address, 80)),
        (PacketType.WRITE, write_payload(BY_NAME["length"].address, 5)),
        (0x42, b""),
    ]
    expected_errors = dict.fromkeys(LINK_COUNTERS, 0)
    answered = 0
    for number in range(FUZZ_FRAMES):
        type, payload = rng.choice(valid)
        frame = protocol.encode_frame(type, tb.encoder.seq, payload)
        kind = rng.random()
        if kind < 0.3:
            tb.encoder.seq = (tb.encoder.seq + 1) % 256
            want = tb.model.command(type.value if isinstance(type, PacketType) else type,
                                    (tb.encoder.seq - 1) % 256, payload)
            await tb.source.send(frame)
            reply = await tb.next_packet(types={PacketType.ACK, PacketType.NAK,
                                                PacketType.IDENTITY, PacketType.REGISTERS,
                                                PacketType.STATUS})
            if reply.type != PacketType.STATUS:
                assert (reply.type, reply.payload) == want, (number, type, payload, reply, want)
            answered += 1
            continue
        # Damage the frame: flip bits, cut it short, or replace it with noise; keep the
        # delimiter at the end so that each damaged frame is one frame.
        body = bytearray(frame[:-1])
        if kind < 0.6:
            for _ in range(rng.randint(1, 3)):
                position = rng.randrange(len(body))
                body[position] ^= 1 << rng.randrange(8)
        elif kind < 0.8:
            body = body[:rng.randrange(1, len(body))]
        elif kind < 0.95:
            body = bytearray(rng.getrandbits(8) for _ in range(rng.randint(1, 40)))
        else:
            body = bytearray(rng.randrange(1, 256) for _ in range(MAX_ENCODED + 1 +
                                                                     rng.randrange(10)))
        body = bytearray(byte if byte else 0x55 for byte in body)   # no delimiter inside
        wire = bytes(body) + b"\x00"
        check = protocol.FrameDecoder(synced=True).feed(wire)
        await tb.source.send(wire)
        if check and isinstance(check[0], protocol.LinkError):
            expected_errors[check[0].code] += 1
            reply = await tb.next_packet(types={PacketType.NAK})
            assert reply.payload == protocol.pack(Nak, code=check[0].code), \
                (number, check, reply)
        elif check:
            # A mutation that still decodes: a valid command (not counted as an error).
            packet = check[0]
            reply = await tb.next_packet(types={PacketType.ACK, PacketType.NAK,
                                                PacketType.IDENTITY, PacketType.REGISTERS,
                                                PacketType.STATUS})
            want = tb.model.command(packet.type.value if isinstance(packet.type, PacketType)
                                    else packet.type, packet.seq, packet.payload)
            if reply.type != PacketType.STATUS:
                assert (reply.type, reply.payload) == want, (number, packet, reply, want)
        answered += 1
    status = await tb.status()
    for code, name in LINK_COUNTERS.items():
        assert status[name] == expected_errors[code], (name, status[name], expected_errors)
    assert sum(expected_errors.values()) > FUZZ_FRAMES // 2
    # The settings are those the model accepted, nothing else.
    reply = await tb.command(PacketType.READ, read_payload(0, len(REGISTERS)))
    assert not [r for r in tb.link_reports if not isinstance(r, protocol.SequenceGap)]
    dut._log.info("%d frames, errors %s", FUZZ_FRAMES,
                  {code.name: count for code, count in expected_errors.items()})


async def _acquire(tb, **settings):
    await tb.write(**settings)
    await tb.command(PacketType.START)


@cocotb.test()
async def test_raw_events_closed_loop(dut):
    """Raw mode: every event the sensor model put on the bus inside the gate comes back, bit
    for bit, with the index of the laser cycle it followed; STATUS counts the others as outside
    the gate, and the pulses."""
    tb = TopTB(dut)
    await tb.start()
    gate_start, gate_end = 1000, 6000
    await _acquire(tb, acquisition=AcquisitionMode.RAW.value, delay_mode=2, mask_width=5,
                   seed=0xBEEF, gate_start=gate_start, gate_end=gate_end)
    tb.start_sensor(random.Random(5), 0.3)
    await Timer(400, unit="us")
    tb.stop_sensor()
    await ClockCycles(tb.dut.clk, 200)
    await tb.command(PacketType.STOP)
    # (the events still in the FIFO drain over the link: longer at a board's slower baud)
    await Timer(300 * max(1, 12_000_000 // BAUD), unit="us")
    tb._drain()
    events = [protocol.unpack_events(p.payload) for p in tb.data_packets + tb.packets
              if p.type == PacketType.EVENTS]
    got = np.concatenate(events) if events else np.zeros(0, EVENT_DTYPE)
    dut._log.info("status %s, packets %s", await tb.status(),
                  [(p.type, p.seq, len(p.payload)) for p in tb.data_packets + tb.packets][:20])
    sent = np.array(tb.sensor_events, dtype=[("timestamp", "u2"), ("address", "u1"),
                                             ("collision", "u1"), ("pulse", "u4")])
    inside = (sent["timestamp"] >= gate_start) & (sent["timestamp"] <= gate_end)
    want = sent[inside]
    assert len(want) > 50 and (~inside).sum() > 20
    assert len(got) == len(want), (len(got), len(want))
    for name in ("timestamp", "address", "collision", "pulse"):
        assert np.array_equal(got[name], want[name]), (name, got[name][:8], want[name][:8])
    status = await tb.status()
    assert status == {**dict.fromkeys(STATUS_FIELDS, 0), "pulses": tb.pulses,
                      "events": len(want), "dropped_gate": int((~inside).sum()),
                      "commands": status["commands"]}, status


@cocotb.test()
async def test_histogram_closed_loop(dut):
    """Histogram mode: the first frame equals the histogram of the events the sensor model
    produced during it (all of pixel 0: the frame's one pixel by default)."""
    tb = TopTB(dut)
    await tb.start()
    shift = 6   # 128 bins: one chunk per frame
    integration = 40_000
    await _acquire(tb, delay_mode=1, length=5, seed=3, bin_shift=shift,
                   integration=integration)
    tb.start_sensor(random.Random(9), 0.6, addresses=1)
    # Stop the photons well before the first frame ends.
    await ClockCycles(tb.dut.clk, integration - 3000)
    tb.stop_sensor()
    await ClockCycles(tb.dut.clk, 4000)
    await tb.command(PacketType.STOP)
    chunks = []
    deadline = get_sim_time("us") + 2000
    while not chunks and get_sim_time("us") < deadline:
        tb._drain()
        chunks = [p for p in tb.data_packets + tb.packets if p.type in HISTOGRAM_TYPES]
        await Timer(20, unit="us")
    assert chunks, "no histogram"
    # (a full or a compact chunk, whichever the board found shorter)
    chunk = decode_chunk(chunks[0].type, chunks[0].payload)
    frame, first_bin, chunk_shift, last = chunk.frame, chunk.first_bin, chunk.shift, chunk.last
    counts = chunk.counts
    want = np.bincount(np.array([e[0] for e in tb.sensor_events]) >> shift,
                       minlength=8192 >> shift)
    assert (frame, first_bin, chunk_shift, last) == (0, 0, shift, 1)
    assert len(tb.sensor_events) > 100
    assert np.array_equal(counts, want)


@cocotb.test()
async def test_keyed_last_iv(dut):
    """Keyed mode with the last IV (``2**80 - 1``): one run fires; after it STATUS ``ivs_used_up``
    reads 1 and the next run fires nothing (never IV 0 again under the key); a new key ends it
    (its run uses the last IV again). Every reply, STATUS included, against the command model."""
    tb = TopTB(dut)
    await tb.start()
    words = {f"iv{k}": ((1 << 80) - 1 >> (32 * k)) & 0xFFFFFFFF for k in range(3)}
    await tb.write(**words, key0=0x89ABCDEF, key1=0x01234567, key2=0x0123,
                   delay_mode=3, mask_width=4, period=40)

    async def run():
        before = tb.pulses
        await tb.command(PacketType.START)
        await ClockCycles(tb.dut.clk, 4000)
        await tb.command(PacketType.STOP)
        await ClockCycles(tb.dut.clk, 200)
        return tb.pulses - before, (await tb.status())["ivs_used_up"]

    first, again = await run(), await run()
    await tb.write(key0=0x42)
    assert (await tb.status())["ivs_used_up"] == 0
    renewed = await run()
    assert first[0] > 40 and again == (0, 1) and renewed[0] > 40, (first, again, renewed)
    assert first[1] == renewed[1] == 1


async def inject_events(tb, rng, count, *, pixel_bits, first_pixel):
    """Drive ``count`` random events straight onto the sensor bus, at least 5 cycles apart
    (the strobe high 2 cycles, low at least 3): addresses mostly those of the frame, some
    others; timestamps over all codes; one in five flagged as a collision. Returns them as
    (timestamp, address, collision) arrays."""
    dut = tb.dut
    pixels = range(first_pixel, first_pixel + (1 << pixel_bits))
    others = [address for address in range(64) if address not in pixels]
    events = []
    for _ in range(count):
        inside = not others or rng.random() < 0.75
        address = rng.choice(pixels) if inside else rng.choice(others)
        event = (rng.randrange(8192), address, int(rng.random() < 0.2))
        dut.sensor_timestamp.value, dut.sensor_address.value, dut.sensor_collision.value = \
            event
        await ClockCycles(dut.clk, 1)
        dut.sensor_valid.value = 1
        await ClockCycles(dut.clk, 2)
        dut.sensor_valid.value = 0
        await ClockCycles(dut.clk, 3 + rng.randrange(4))
        events.append(event)
    return tuple(np.array(column, dtype=np.int64) for column in zip(*events))


async def histogram_frame(tb, frame, bins, *, timeout_us=20_000, split=None):
    """The counts of histogram ``frame``, from its chunks (full or compact, as the board chose),
    once all ``bins`` have come. ``split``, if given, is the ``(pixel_bits, first_pixel)`` the
    frame's header must carry."""
    deadline = get_sim_time("us") + timeout_us
    while get_sim_time("us") < deadline:
        tb._drain()
        got = assemble((packet.type, packet.payload)
                       for packet in tb.data_packets + tb.packets).get(frame)
        if got is not None and got[2]:
            chunk, counts, _ = got
            assert len(counts) == bins, f"frame {frame}: {len(counts)} bins, not {bins}"
            if split is not None:
                assert (chunk.pixel_bits, chunk.first_pixel) == split, \
                    f"frame {frame}: chunk header split {(chunk.pixel_bits, chunk.first_pixel)}"
            return counts
        await Timer(50, unit="us")
    raise AssertionError(f"frame {frame}: not all of its {bins} bins came")


#: Splits of the pixel histogram test: pixel_bits, first_pixel, bin_shift, collisions (drop
#: them); all fit a bank of 2**14 bins (the iCEBreaker's).
PIXEL_SPLITS = [(2, 7, 8, 1), (6, 0, 10, 0), (0, 37, 6, 1), (3, 56, 9, 1)]


@cocotb.test()
async def test_pixel_histograms(dut):
    """Histograms by (pixel, bin): random (address, timestamp, collision) events on the sensor
    bus, under several pixel splits; each frame equals the per-pixel bincount of the events
    injected during it, bit for bit, and STATUS counts the events dropped as collisions and
    for addresses outside the frame's pixels."""
    tb = TopTB(dut)
    await tb.start()
    tb.data_packets = []        # (this test's packets only)
    rng = random.Random(17)
    before = await tb.status()
    # (a smaller build takes fewer pixels: the splits it takes)
    splits = [split for split in PIXEL_SPLITS if split[0] <= MAXIMA.get("pixel_bits", 6)]
    for frame, (pixel_bits, first_pixel, shift, drop) in enumerate(splits):
        # One frame per split: a long integration, ended by STOP. The histogram's settings
        # in one WRITE (one at a time, some orders would pass through splits that do not fit).
        names = ("bin_shift", "integration", "collisions", "pixel_bits", "first_pixel",
                 "full_readout")
        values = dict(bin_shift=shift, integration=10_000_000, collisions=drop,
                      pixel_bits=pixel_bits, first_pixel=first_pixel, full_readout=1)
        addresses = [BY_NAME[name].address for name in names]
        assert addresses == list(range(addresses[0], addresses[0] + len(names)))
        reply = await tb.command(PacketType.WRITE, protocol.pack(
            registers_layout(len(names)), address=addresses[0],
            values=[values[name] for name in names]))
        assert reply.type == PacketType.ACK, reply
        await tb.command(PacketType.START)
        timestamps, addresses, collisions = await inject_events(
            tb, rng, 300, pixel_bits=pixel_bits, first_pixel=first_pixel)
        await ClockCycles(dut.clk, 50)
        await tb.command(PacketType.STOP)
        bins = 1 << (13 - shift)
        counts = await histogram_frame(tb, frame, bins << pixel_bits,
                                       split=(pixel_bits, first_pixel))
        # Independently of the models: drop the flagged events if asked, then the other
        # addresses; the rest by pixel and bin.
        kept = collisions == 0 if drop else np.ones(len(timestamps), dtype=bool)
        pixel = addresses - first_pixel
        inside = kept & (pixel >= 0) & (pixel < (1 << pixel_bits))
        want = np.bincount(pixel[inside] * bins + (timestamps[inside] >> shift),
                           minlength=bins << pixel_bits)
        assert np.array_equal(counts, want), (frame, np.flatnonzero(counts != want)[:8])
        after = await tb.status()
        delta = {name: after[name] - before[name] for name in
                 ("events", "frames", "dropped_collision", "dropped_pixel",
                  "dropped_histogram", "histogram_overflow", "dropped_gate")}
        assert delta == {"events": int(kept.sum()), "frames": 1,
                         "dropped_collision": int((~kept).sum()),
                         "dropped_pixel": int((kept & ~inside).sum()),
                         "dropped_histogram": 0, "histogram_overflow": 0,
                         "dropped_gate": 0}, (frame, delta)
        assert inside.sum() > 150 and (not drop or (~kept).sum() > 30)
        assert pixel_bits == 6 or (kept & ~inside).sum() > 30
        dut._log.info("split %s: %d events, %d in the frame, %d bins", splits[frame],
                      len(timestamps), int(inside.sum()), len(counts))
        before = after
