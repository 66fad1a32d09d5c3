"""cocotb fuzz of the link (:class:`fliss.sim.benches.link_top.LinkTop`) at one byte per cycle.

Random and mutated frames go in one after the other, each as soon as the previous one is
answered, at one byte per cycle (played by the bench's gateware, so that the test wakes a few
times a frame, not every cycle). Each must come back as its proper reply (the command
processor's model says which) or as a NAK with the reason the software codec finds; every link
error is counted in STATUS; and at the end the registers hold exactly what the model accepted:
no refused setting was applied.
``FLISS_TB_FUZZ_FRAMES`` frames (10 000 by default).
"""

import os
import random

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import ClockCycles, FallingEdge, First, RisingEdge, Timer
from cocotb.utils import get_sim_time

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.protocol import (DEFAULT_BAUD, PacketType, MAX_ENCODED, Nak, ReadRequest, Status,
                             LINK_COUNTERS, registers_layout)
from ...hdl.registers import REGISTERS
from ... import protocol
from ..models.command import CommandModel
from .link_top import PLAY_BYTES, RECORD_BYTES


FRAMES = int(os.environ.get("FLISS_TB_FUZZ_FRAMES", 10_000))
CLOCK_PERIOD_PS = round(1e12 / DEFAULT_CLOCK_HZ)
BAUD = DEFAULT_BAUD   # LinkTop's default: only the identity reports it


def fuzz_frames(rng, count):
    """``count`` frames on the wire: valid commands, bit flips, cuts, noise, oversize, and
    sound CRCs over a wrong length."""
    encoder = protocol.PacketEncoder()
    commands = [
        (PacketType.PING, b""), (PacketType.IDENTIFY, b""), (PacketType.GET_STATUS, b""),
        (PacketType.START, b""), (PacketType.STOP, b""),
        (PacketType.READ, protocol.pack(ReadRequest, address=0, count=5)),
        (PacketType.READ, protocol.pack(ReadRequest, address=30, count=1)),
        (0x42, b""), (PacketType.EVENTS, b""),
    ]
    for register in REGISTERS:
        for value in (register.minimum, register.maximum, register.maximum + 1, 0):
            if value < (1 << 32):
                commands.append((PacketType.WRITE, protocol.pack(
                    registers_layout(1), address=register.address, values=[value])))
    for _ in range(count):
        type, payload = rng.choice(commands)
        seq = encoder.seq
        frame = encoder.frame(type, payload)
        kind = rng.random()
        if kind < 0.35:
            yield frame
        elif kind < 0.4:
            length = (len(payload) + rng.choice([-1, 1, 2, 200])) & 0xffff
            body = protocol.frames._header_bytes(type, seq, length) + payload
            body += protocol.crc16(body).to_bytes(2, "big")
            yield protocol.cobs_encode(body) + b"\x00"
        else:
            body = bytearray(frame[:-1])
            if kind < 0.6:
                for _ in range(rng.randint(1, 3)):
                    body[rng.randrange(len(body))] ^= 1 << rng.randrange(8)
            elif kind < 0.8:
                body = body[:rng.randrange(1, len(body))]
            elif kind < 0.95:
                body = bytearray(rng.getrandbits(8) for _ in range(rng.randint(1, 40)))
            else:
                body = bytearray(rng.randrange(1, 256)
                                 for _ in range(MAX_ENCODED + 1 + rng.randrange(10)))
            yield bytes(b if b else 0x55 for b in body) + b"\x00"


class Link:
    """Host end of the link: sends a frame and collects what comes back, through the bench's
    :class:`~fliss.sim.benches.wire.WireBench` (a few accesses a frame, not one a cycle)."""

    def __init__(self, dut):
        self.dut = dut
        self.decoder = protocol.FrameDecoder(synced=True)
        self.read = 0

    async def exchange(self, wire, *, limit_cycles=2000):
        """Send ``wire`` as fast as the link takes it, then return the one packet or report
        decoded from what came back once it was sent and a frame ended (None if nothing ended
        within ``limit_cycles`` cycles of the last byte).

        Works at falling edges, where inputs set are sampled at the next rising edge.
        """
        dut = self.dut
        assert 0 < len(wire) <= PLAY_BYTES, len(wire)
        dut.frame.value = int.from_bytes(wire, "little")
        dut.length.value = len(wire)
        dut.go.value = 1
        await FallingEdge(dut.clk)
        dut.go.value = 0
        timeout = Timer((len(wire) + limit_cycles) * CLOCK_PERIOD_PS, unit="ps")
        if await First(RisingEdge(dut.answered), timeout) is timeout:
            return None
        await FallingEdge(dut.clk)
        received = int(dut.received.value)
        fresh = received - self.read
        assert fresh <= RECORD_BYTES, f"{fresh} bytes came back: more than the bench records"
        self.read = received
        record = int(dut.record.value).to_bytes(RECORD_BYTES, "little")
        items = [item for item in self.decoder.feed(record[RECORD_BYTES - fresh:])
                 if not isinstance(item, protocol.SequenceGap)]
        assert len(items) == 1, items
        return items[0]


@cocotb.test()
async def test_fuzz(dut):
    """Random and mutated frames, each answered and counted; no refused setting applied."""
    Clock(dut.clk, CLOCK_PERIOD_PS, unit="ps", impl="gpi").start()
    dut.rst.value = 1
    dut.go.value = 0
    await ClockCycles(dut.clk, 3)
    dut.rst.value = 0
    await FallingEdge(dut.clk)

    # One frame at a time, as a host waits for each reply: every frame must be answered.
    link = Link(dut)
    frames = list(fuzz_frames(random.Random(0x11F0), FRAMES))
    read_back = protocol.encode_frame(PacketType.READ, 0,
                                   protocol.pack(ReadRequest, address=0, count=len(REGISTERS)))
    items = []
    for frame in frames + [read_back]:
        items.append(await link.exchange(frame))
    cycles = round(get_sim_time("ps") / CLOCK_PERIOD_PS)

    # What a correct device answers, frame by frame, from the software codec and the command model.
    model = CommandModel(DEFAULT_CLOCK_HZ, BAUD)
    errors = dict.fromkeys(LINK_COUNTERS, 0)
    accepted = 0
    for number, (frame, reply) in enumerate(zip(frames, items)):
        assert isinstance(reply, protocol.Packet), (number, reply)
        expected = protocol.FrameDecoder(synced=True).feed(frame)[0]
        if isinstance(expected, protocol.LinkError):
            errors[expected.code] += 1
            assert (reply.type, reply.payload) == (
                PacketType.NAK, protocol.pack(Nak, code=expected.code)), \
                (number, frame.hex(), expected, reply)
            continue
        type = expected.type.value if isinstance(expected.type, PacketType) else expected.type
        want = model.command(type, expected.seq, expected.payload)
        if reply.type == PacketType.STATUS:
            got = protocol.unpack(Status, reply.payload)
            assert {name: got[name] for name in LINK_COUNTERS.values()} == \
                {name: errors[code] for code, name in LINK_COUNTERS.items()}, number
            assert (got["commands"], got["refused"], got["running"]) == \
                (model.commands, model.refused, int(model.running)), number
        else:
            assert (reply.type, reply.payload) == (want[0], want[1]), \
                (number, expected, reply, want)
        accepted += want[0] == PacketType.ACK

    # Nothing refused was applied: the registers are the model's.
    values = protocol.unpack(registers_layout(len(REGISTERS)), items[-1].payload)["values"]
    assert dict(zip((r.name for r in REGISTERS), values)) == \
        {r.name: model.read_value(r) for r in REGISTERS}
    assert accepted > FRAMES // 20 and all(count > FRAMES // 200 for count in errors.values())
    dut._log.info("%d frames in %d cycles: %d commands accepted, link errors %s", FRAMES,
                  cycles, accepted, {code.name: count for code, count in errors.items()})
