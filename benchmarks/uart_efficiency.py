"""UART payload efficiency of raw event streaming, next to one event per frame.

Definitions (8N1: every byte on the line is a 10-bit character, start + 8 data + stop):

* framing efficiency = payload bytes / line characters, the characters being every byte of the
  frame: COBS code bytes, header, payload, CRC and delimiter. This is the figure the issue asks
  to be at least 0.9.
* line efficiency = payload bits / line bit times = 0.8 x framing efficiency: the fraction of
  the line's raw bit rate that carries event bits, start and stop bits counted as overhead.

Payload is the EVENTS packet payload: EVENT_BYTES bytes per event. Frame sizes are measured by
encoding random events with the software codec; then the gateware (FrameEncoder into UartTx at
12 Mbaud from 80 MHz) is simulated for the baseline and for full packets, and the cycles from
the first start bit to the last stop bit give the payload rate actually achieved.

Run: .venv/bin/python benchmarks/uart_efficiency.py
"""

import numpy as np
from amaranth.hdl import Module, Signal
from amaranth.lib import wiring
from amaranth.sim import Simulator

from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.hdl.link.framing import FrameEncoder
from fliss.hdl.protocol import PacketType, EVENT_BYTES, MAX_EVENTS_PER_PACKET, MAX_PAYLOAD
from fliss.hdl.link.uart import UartTx, CHARACTER_BITS, DATA_BITS
from fliss import protocol
from fliss.protocol.events import EVENT_DTYPE


BAUDS = [115_200, 3_000_000, 12_000_000]


def random_events(rng, count, pulse0=0):
    events = np.zeros(count, dtype=EVENT_DTYPE)
    events["timestamp"] = rng.integers(0, 1 << 13, count)
    events["address"] = rng.integers(0, 60, count)
    events["collision"] = rng.random(count) < 0.05
    events["pulse"] = pulse0 + np.sort(rng.integers(0, 4 * count, count))
    return events


def frames_for(rng, events_total, batch):
    """Frames (codec bytes) carrying `events_total` events, `batch` per EVENTS packet."""
    frames = []
    for seq, start in enumerate(range(0, events_total, batch)):
        events = random_events(rng, min(batch, events_total - start), pulse0=start)
        frames.append(protocol.encode_frame(PacketType.EVENTS, seq % 256,
                                         protocol.pack_events(events)))
    return frames


def simulate_line_cycles(frames, baud):
    """Cycles the gateware takes to put `frames` on the line: encoder into UartTx."""
    packets = []
    decoder = protocol.FrameDecoder(synced=True)
    for frame in frames:
        packets += [p for p in decoder.feed(frame) if isinstance(p, protocol.Packet)]
    m = Module()
    m.submodules.encoder = encoder = FrameEncoder()
    m.submodules.tx = tx = UartTx(clock_hz=DEFAULT_CLOCK_HZ, baud=baud)
    wiring.connect(m, encoder.o, tx.i)
    cycle = Signal(32)
    m.d.sync += cycle.eq(cycle + 1)
    marks = {}

    async def send(ctx):
        for packet in packets:
            header = {"type": packet.type.value, "seq": packet.seq, "length": len(packet.payload)}
            beats = [{"header": header, "first": 1, "last": int(not packet.payload)}]
            beats += [{"header": header, "data": b, "last": int(i == len(packet.payload) - 1)}
                      for i, b in enumerate(packet.payload)]
            for beat in beats:
                ctx.set(encoder.i.valid, 1)
                ctx.set(encoder.i.payload, beat)
                await ctx.tick().until(encoder.i.ready)
        ctx.set(encoder.i.valid, 0)

    async def watch(ctx):
        await ctx.negedge(tx.tx)
        marks["first"] = ctx.get(cycle)
        while True:
            await ctx.negedge(tx.busy)
            marks["last"] = ctx.get(cycle)

    async def wait(ctx):
        total = sum(len(f) for f in frames) * ((CHARACTER_BITS * DEFAULT_CLOCK_HZ) // baud + 2)
        await ctx.tick().repeat(total + 1000)

    sim = Simulator(m)
    sim.add_clock(1 / DEFAULT_CLOCK_HZ)
    sim.add_testbench(send)
    sim.add_testbench(wait)
    sim.add_testbench(watch, background=True)
    sim.run()
    return marks["last"] - marks["first"]


def main():
    rng = np.random.default_rng(2019)
    events_total = MAX_EVENTS_PER_PACKET * 8
    print(f"EVENTS payload: {EVENT_BYTES} bytes per event, at most {MAX_EVENTS_PER_PACKET} "
          f"events per packet; {events_total} random events per row")
    print(f"framing eff. = payload bytes / line characters; line eff. = payload bits / line bit "
          f"times = {DATA_BITS / CHARACTER_BITS:.1f} x framing eff.")
    print()
    header = f"{'events/frame':>12} {'frame bytes':>11} {'framing eff.':>12} {'line eff.':>9}"
    header += "".join(f" {'Mev/s @' + format(b / 1e6, 'g') + 'M':>13}" for b in BAUDS)
    print(header)
    rows = {}
    batches = [1, 2, 4, 8, 16, 32, MAX_EVENTS_PER_PACKET]
    for batch in batches:
        frames = frames_for(rng, events_total, batch)
        line_bytes = sum(len(f) for f in frames)
        payload = events_total * EVENT_BYTES
        eff = payload / line_bytes
        rows[batch] = (frames, eff)
        label = f"{batch}" + (" (baseline)" if batch == 1 else
                              " (max)" if batch == MAX_EVENTS_PER_PACKET else "")
        line = f"{label:>12} {line_bytes / len(frames):11.1f} {eff:12.3f} "
        line += f"{eff * DATA_BITS / CHARACTER_BITS:9.3f}"
        for baud in BAUDS:
            rate = baud / CHARACTER_BITS / line_bytes * events_total
            line += f" {rate / 1e6:13.4f}"
        print(line)

    print()
    baud = 12_000_000
    print(f"Gateware, FrameEncoder into UartTx at {baud / 1e6:g} Mbaud from "
          f"{DEFAULT_CLOCK_HZ / 1e6:g} MHz, simulated:")
    print(f"{'events/frame':>12} {'events':>6} {'cycles':>8} {'payload MB/s':>12} "
          f"{'framing eff. x ideal char rate':>31} {'achieved/ideal':>14}")
    for batch in (1, MAX_EVENTS_PER_PACKET):
        frames, eff = rows[batch]
        count = 2 * MAX_EVENTS_PER_PACKET
        kept = frames_for(np.random.default_rng(1), count, batch)
        cycles = simulate_line_cycles(kept, baud)
        payload = count * EVENT_BYTES
        achieved = payload / (cycles / DEFAULT_CLOCK_HZ)
        line_bytes = sum(len(f) for f in kept)
        ideal = payload / line_bytes * baud / CHARACTER_BITS
        label = f"{batch}" + (" (baseline)" if batch == 1 else " (max)")
        print(f"{label:>12} {count:6d} {cycles:8d} {achieved / 1e6:12.4f} {ideal / 1e6:31.4f} "
              f"{achieved / ideal:14.4f}")
    # Worst case for the COBS encoder: no zero byte at all, so every block is a full 254-byte
    # run that must be collected before its code byte can be sent.
    payload = bytes(np.random.default_rng(2).integers(1, 256, MAX_PAYLOAD, dtype=np.uint8))
    kept = [protocol.encode_frame(PacketType.HISTOGRAM, seq, payload) for seq in range(2)]
    cycles = simulate_line_cycles(kept, baud)
    line_bytes = sum(len(f) for f in kept)
    achieved = 2 * MAX_PAYLOAD / (cycles / DEFAULT_CLOCK_HZ)
    ideal = 2 * MAX_PAYLOAD / line_bytes * baud / CHARACTER_BITS
    print(f"{'no zeros':>12} {'-':>6} {cycles:8d} {achieved / 1e6:12.4f} {ideal / 1e6:31.4f} "
          f"{achieved / ideal:14.4f}")
    print(f"{'':>12} ({MAX_PAYLOAD}-byte payloads without a zero byte; the difference is the "
          f"start-up latency: the first run is collected before its code byte can go)")
    print()
    print("ideal = framing eff. x baud / 10; achieved/ideal below 1 would mean idle line time "
          "between characters or frames.")


if __name__ == "__main__":
    main()
