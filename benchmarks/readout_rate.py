"""Histogram readout rate: full against compact chunks, on the paper's single-pixel bench.

The scene is the paper's (section 4, Table 1): the victim at 1 MHz with FLISS (masked LFSR,
Wm = 6) looking at a wall at 4 m, an aggressor at the victim's effective PRF 75 ns later, and
background (:mod:`fliss.sim.scene`, defaults). :func:`fliss.sim.scene.acquire` gives the events
of consecutive acquisitions of 1, 10 and 100 ms; each acquisition's histogram (8192 bins, one
pixel, bin shift 0) is encoded as the board sends it, once with ``full_readout`` = 1 (the
baseline: every bin as u16, as FLISS did before) and once with the board's choice (compact
chunks where shorter), in the same run.

Link time comes from the exact wire bytes of those packets (header, payload, CRC, COBS,
delimiter: :func:`fliss.protocol.encode_frame`) at 10 bits a byte. The packetizer's time per
frame follows :class:`fliss.hdl.packets.histogram.HistogramPacketizer` at 80 MHz: each
window of 128 bins is taken at the readout's 6 cycles a bin (``READOUT_CYCLES_PER_BIN``: the
ULX3S's banks of 64 block RAMs), a compact window is then encoded (2 cycles an empty bin, 3 a bin
with a count, one a token byte), and a packet the window sends occupies the packetizer until it
is on the wire (conservative: the frame encoder's buffer is not counted). The bank is
free when the last bin is taken; the histogram engine then starts the next frame, or, if the
other bank is still being read out, waits and drops the events meanwhile (``dropped_histogram``).
Frames follow each other as in :class:`fliss.hdl.histogram.frames.FrameSequencer`.

``--cross-check`` (on by default) runs one 1 ms frame through the gateware (packetizer,
arbiter, frame encoder) in Amaranth's simulator with the readout at 6 cycles a bin and a
12 Mbaud UART's pace on its output, and prints its bank and busy times beside this model's.

``--shift`` takes wider bins (``8192 >> shift`` bins of ``2**shift`` codes).

Usage: python benchmarks/readout_rate.py [--frames N] [--seed S] [--shift B] [--no-cross-check]
"""

import argparse
import time

import numpy as np

from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.hdl.histogram.readout import READOUT_CYCLES_PER_BIN
from fliss.hdl.protocol import CHUNK_BINS, MAX_ENCODED, HistogramChunk, HistogramCompact, PacketType
from fliss.sim.models import delay as delay_model
from fliss.sim.models import scheduler
from fliss.protocol.frames import encode_frame
from fliss.protocol.layout import unpack_from
from fliss.protocol.histograms import encode_histogram, tokens
from fliss.sim.scene import Aggressor, Scene, acquire


INTEGRATIONS_S = (1e-3, 10e-3, 100e-3)
BAUDS = (3_000_000, 12_000_000)
BITS_PER_BYTE = 10          # 8N1
CLOCK_HZ = DEFAULT_CLOCK_HZ
BINS = 8192


def paper_scene():
    """The paper's bench: FLISS masked Wm = 6, aggressor at the effective PRF, 4 m wall."""
    victim = scheduler.Settings(mode=delay_model.parse_mode("masked"), mask_width=6, period=80)
    mean = float(delay_model.mean_delay(victim.mode, length=victim.length,
                                        mask_width=victim.mask_width))
    return Scene(victim=victim, aggressors=(Aggressor(period_cycles=80 + mean),))


def wire_bytes(packets):
    """Bytes on the wire of ``packets`` (sequence numbers do not change the length much; the
    first frame's are used)."""
    return [len(encode_frame(type, index % 256, payload))
            for index, (type, payload) in enumerate(packets)]


def frame_timing(counts, packets, baud):
    """``(bank_s, busy_s)`` of one frame: time from the readout's start until the last bin is
    taken (the bank is free), and until the packetizer is ready for the next frame."""
    window = min(CHUNK_BINS, len(counts))
    windows = len(counts) // window
    sizes = wire_bytes(packets)
    sent_after = [0.0] * windows        # link seconds of the packets sent after each window
    compact_windows = set()
    for (type, payload), size in zip(packets, sizes):
        if type == PacketType.HISTOGRAM_COMPACT:
            header = unpack_from(HistogramCompact, payload)
            first, last = header["first_bin"], header["last_bin"]
            compact_windows.update(range(first // window, last // window + 1))
            after = windows - 1 if last == len(counts) - 1 else (last + 1) // window
        else:
            after = unpack_from(HistogramChunk, payload)["first_bin"] // window
        sent_after[after] += size * BITS_PER_BYTE / baud
    cycles_scan = READOUT_CYCLES_PER_BIN * window / CLOCK_HZ
    t = 0.0
    bank = 0.0
    for index in range(windows):
        t += cycles_scan
        bank = t
        if index in compact_windows:
            part = counts[index * window:(index + 1) * window]
            # (two cycles an empty bin, three and one a token byte for a count)
            t += (2 * window + np.count_nonzero(part) + len(tokens(part)[0])) / CLOCK_HZ
        t += sent_after[index]
    return bank, t


def steady_state(frames, t_int_s):
    """Histograms per second and events dropped per histogram over consecutive frames:
    ``frames`` = [(events, bank_s, busy_s)], filled and read out as the frame sequencer does."""
    start, bank_free, packetizer_free = 0.0, 0.0, 0.0
    dropped = 0.0
    swaps = []
    for events, bank_s, busy_s in frames:
        end = start + t_int_s
        swap = max(end, bank_free)          # waits for the other bank: events dropped
        dropped += events / t_int_s * (swap - end)
        begin = max(swap, packetizer_free)  # the readout of this frame
        bank_free, packetizer_free = begin + bank_s, begin + busy_s
        swaps.append(swap)
        start = swap
    period = (swaps[-1] - swaps[0]) / (len(swaps) - 1)
    return 1 / period, dropped / len(frames)


def cross_check(counts, baud, shift):
    """Bank and busy time of ``counts`` (one frame) through the gateware in Amaranth's
    simulator, readout at 4 cycles a bin, output at the UART's pace."""
    from amaranth.sim import Simulator
    from fliss.sim.benches.histogram_link_top import HistogramLinkTop

    dut = HistogramLinkTop()
    byte_cycles = round(BITS_PER_BYTE * CLOCK_HZ / baud)
    result = {}

    async def bench(ctx):
        ctx.set(dut.shift, shift)
        cycle, position, wait, out, idle = 0, 0, 0, 0, 0
        while True:
            if position < len(counts) and wait == 0:
                ctx.set(dut.readout.valid, 1)
                ctx.set(dut.readout.p.index, position)
                ctx.set(dut.readout.p.count, int(counts[position]))
                ctx.set(dut.readout.p.last, position == len(counts) - 1)
            else:
                ctx.set(dut.readout.valid, 0)
            ctx.set(dut.tx.ready, cycle % byte_cycles == 0)
            _, _, took, sent = await ctx.tick().sample(
                dut.readout.valid & dut.readout.ready, dut.tx.valid & dut.tx.ready)
            cycle += 1
            wait = max(wait - 1, 0)
            if took:
                position += 1
                wait = READOUT_CYCLES_PER_BIN - 1
                if position == len(counts):
                    result["bank"] = cycle
            if sent:
                out += 1
                result["busy"] = cycle
                idle = 0
            elif position == len(counts):
                idle += 1
                if idle > 4 * byte_cycles + 2 * MAX_ENCODED:   # (a packet passes the encoder)
                    break
        result["bytes"] = out

    sim = Simulator(dut)
    sim.add_clock(1 / CLOCK_HZ)
    sim.add_testbench(bench)
    sim.run()
    return result["bank"] / CLOCK_HZ, result["busy"] / CLOCK_HZ, result["bytes"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--frames", type=int, default=12, help="acquisitions per integration")
    parser.add_argument("--seed", type=int, default=1, help="seed of the photon statistics")
    parser.add_argument("--shift", type=int, default=0, choices=range(14),
                        help="bin shift: bins of 2**shift TDC codes")
    parser.add_argument("--no-cross-check", dest="cross_check", action="store_false",
                        help="skip the gateware simulation of one frame")
    args = parser.parse_args()

    scene = paper_scene()
    started = time.perf_counter()
    print(f"Histogram readout, the paper's bench (victim 4 m, FLISS masked Wm = 6, aggressor, "
          f"background {scene.background_hz:.0e} Hz), {BINS >> args.shift} bins, "
          f"{args.frames} frames each, "
          f"packetizer at {CLOCK_HZ / 1e6:.0f} MHz, 8N1")
    print(f"{'T_int':>6} {'baud':>5} {'events':>7} {'form':>8} {'bytes/hist':>10} "
          f"{'link ms':>8} {'busy ms':>8} {'hist/s':>7} {'dropped/hist':>13} {'dropped %':>9}")
    aims = {}
    first_frame = None
    for t_int_s in INTEGRATIONS_S:
        run = acquire(scene, t_int_s, args.frames, seed=args.seed, keep_events=True)
        histograms = [np.bincount(events["timestamp"].astype(np.int64), minlength=BINS)
                      for events in run.events]
        assert all(np.array_equal(h, g) for h, g in zip(histograms, run.histograms))
        histograms = [h.reshape(-1, 1 << args.shift).sum(axis=1) for h in histograms]
        events = [len(e) for e in run.events]
        if first_frame is None:
            first_frame = histograms[0]
        for baud in BAUDS:
            for form, full in (("full", True), ("compact", False)):
                frames, sizes, links = [], [], []
                for number, counts in enumerate(histograms):
                    packets = encode_histogram(counts, frame=number, shift=args.shift,
                                               full_readout=full)
                    size = sum(wire_bytes(packets))
                    bank_s, busy_s = frame_timing(counts, packets, baud)
                    frames.append((events[number], bank_s, busy_s))
                    sizes.append(size)
                    links.append(size * BITS_PER_BYTE / baud)
                rate, dropped = steady_state(frames, t_int_s)
                mean_events = np.mean(events)
                print(f"{t_int_s * 1e3:>4.0f}ms {baud / 1e6:>4.0f}M {mean_events:>7.0f} "
                      f"{form:>8} {np.mean(sizes):>10.0f} {np.mean(links) * 1e3:>8.2f} "
                      f"{np.mean([f[2] for f in frames]) * 1e3:>8.2f} {rate:>7.1f} "
                      f"{dropped:>13.0f} {100 * dropped / (mean_events + dropped):>8.1f}%")
                aims[(t_int_s, baud, form)] = dropped
    print(f"(modelled in {time.perf_counter() - started:.1f} s)")
    for t_int_s, baud in ((10e-3, 3_000_000), (1e-3, 12_000_000)):
        for form in ("full", "compact"):
            dropped = aims[(t_int_s, baud, form)]
            print(f"aim: no events dropped at {t_int_s * 1e3:.0f} ms and {baud / 1e6:.0f} Mbaud, "
                  f"{form}: {'met' if dropped == 0 else f'NOT met ({dropped:.0f} per histogram)'}")

    if args.cross_check:
        baud = 12_000_000
        packets = encode_histogram(first_frame, frame=0, shift=args.shift)
        bank_s, busy_s = frame_timing(first_frame, packets, baud)
        started = time.perf_counter()
        sim_bank, sim_busy, sim_bytes = cross_check(first_frame, baud, args.shift)
        print(f"cross-check, one 1 ms frame, compact, 12 Mbaud: gateware {sim_bytes} bytes, "
              f"bank free after {sim_bank * 1e3:.3f} ms, last byte out after "
              f"{sim_busy * 1e3:.3f} ms; model {sum(wire_bytes(packets))} bytes, "
              f"{bank_s * 1e3:.3f} ms, {busy_s * 1e3:.3f} ms "
              f"(simulated in {time.perf_counter() - started:.0f} s)")


if __name__ == "__main__":
    main()
