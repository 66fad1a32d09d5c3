"""Host decode speed (issue 5): can the client keep up with the link, and how close does decoding
plus histogramming of recorded raw data come to ``numpy.bincount`` alone?

Recorded data: a stream of full EVENTS frames (37 events each) and a stream of HISTOGRAM chunks,
encoded with the host codec exactly as the gateware sends them, with scene-simulator events.

Figures, all measured in the same run on the same data:

* decode + histogram: the client's path (``FrameDecoder`` with CRC and sequence checks, the
  ``StreamAssembler`` that unpacks the events, then ``numpy.bincount`` of their timestamps).
* ``numpy.bincount`` alone over the same timestamps, already in memory.
* ratio = events per second of the first over the second (the issue's aim: at least 0.5).
* bytes per second decoded, against what a 12 Mbaud line carries: 1.2 MB/s (10-bit characters).

Run: .venv/bin/python benchmarks/host_decode.py [--events N]
"""

import argparse
import time

import numpy as np

from fliss.hdl.protocol import PacketType, MAX_EVENTS_PER_PACKET
from fliss.hdl.registers import defaults
from fliss.host.client import StreamAssembler, HistogramFrame, EventBatch
from fliss.host.protocol import FrameDecoder, Packet, encode_frame, pack_events
from fliss.sim.model_board import scene_for
from fliss.sim.scene import Scene, Simulation


LINE_BYTES_PER_S = 12_000_000 / 10
READ_BYTES = 4096      # bytes per read from the port


def recorded_events(count, seed=1):
    settings = defaults(80_000_000)
    simulation = Simulation(scene_for(settings, Scene(detections_per_pulse=0.2)), seed=seed)
    pieces, total = [], 0
    while total < count:
        events = simulation.step().events
        pieces.append(events)
        total += len(events)
    return np.concatenate(pieces)[:count]


def event_stream(events):
    frames = []
    for seq, start in enumerate(range(0, len(events), MAX_EVENTS_PER_PACKET)):
        batch = events[start:start + MAX_EVENTS_PER_PACKET]
        frames.append(encode_frame(PacketType.EVENTS, seq % 256, pack_events(batch)))
    return b"".join(frames)


def histogram_stream(histograms):
    frames, seq = [], 0
    for number, counts in enumerate(histograms):
        for first in range(0, len(counts), 128):
            payload = np.array([number], "<u4").tobytes() + \
                np.array([first], "<u2").tobytes() + \
                bytes([0, int(first + 128 >= len(counts))]) + \
                counts[first:first + 128].astype("<u2").tobytes()
            frames.append(encode_frame(PacketType.HISTOGRAM, seq % 256, payload))
            seq += 1
    return b"".join(frames)


def decode(stream):
    """The client's receive path, fed in reads of READ_BYTES; returns the items and the
    decoder."""
    decoder = FrameDecoder(synced=True)
    assembler = StreamAssembler()
    items = []
    for start in range(0, len(stream), READ_BYTES):
        for item in decoder.feed(stream[start:start + READ_BYTES]):
            if isinstance(item, Packet):
                items += assembler.add(item, 0.0)
    items += assembler.flush(0.0)
    return items, decoder


def best_of(function, repeat):
    best, result = None, None
    for _ in range(repeat):
        start = time.perf_counter()
        result = function()
        elapsed = time.perf_counter() - start
        best = elapsed if best is None else min(best, elapsed)
    return best, result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--events", type=int, default=200_000, help="events in the recording")
    parser.add_argument("--repeat", type=int, default=3, help="timing runs (best is kept)")
    args = parser.parse_args(argv)

    events = recorded_events(args.events)
    stream = event_stream(events)
    stamps = events["timestamp"].astype(np.int64)

    def host():
        items, decoder = decode(stream)
        batches = [item.events["timestamp"] for item in items if isinstance(item, EventBatch)]
        return np.bincount(np.concatenate(batches).astype(np.int64), minlength=8192), decoder

    t_host, (histogram, decoder) = best_of(host, args.repeat)
    t_numpy, reference = best_of(lambda: np.bincount(stamps, minlength=8192), 20)
    assert np.array_equal(histogram, reference), "decoded histogram differs"
    assert decoder.counters.dropped_frames == 0 and decoder.counters.missing_packets == 0

    print(f"raw events: {len(events)} events in {len(stream)} bytes "
          f"({len(stream) / len(events):.2f} bytes per event on the wire)")
    print(f"  decode + histogram: {t_host * 1e3:8.1f} ms  {len(events) / t_host / 1e6:8.3f} "
          f"Mevents/s  {len(stream) / t_host / 1e6:6.2f} MB/s")
    print(f"  numpy.bincount:     {t_numpy * 1e3:8.3f} ms  {len(events) / t_numpy / 1e6:8.1f} "
          f"Mevents/s")
    ratio = t_numpy / t_host
    print(f"  ratio (decode + histogram / bincount, events per second): {ratio:.4f} "
          f"(aim >= 0.5: {'met' if ratio >= 0.5 else 'NOT met'})")
    speed = len(stream) / t_host
    print(f"  keeps up with 12 Mbaud (1.2 MB/s): {'yes' if speed >= LINE_BYTES_PER_S else 'NO'}"
          f" ({speed / LINE_BYTES_PER_S:.2f} x line rate)")

    rng = np.random.default_rng(3)
    histograms = rng.poisson(5.0, (20, 8192))
    hstream = histogram_stream(histograms)
    t_hist, (items, decoder) = best_of(lambda: decode(hstream), args.repeat)
    frames = [item for item in items if isinstance(item, HistogramFrame)]
    assert len(frames) == 20 and all(f.complete for f in frames)
    assert np.array_equal(np.array([f.counts for f in frames]), histograms)
    speed = len(hstream) / t_hist
    print(f"histograms: 20 x 8192 bins in {len(hstream)} bytes")
    print(f"  decode + reassembly: {t_hist * 1e3:8.1f} ms  {speed / 1e6:6.2f} MB/s  "
          f"{20 / t_hist:8.1f} histograms/s")
    print(f"  keeps up with 12 Mbaud (1.2 MB/s): {'yes' if speed >= LINE_BYTES_PER_S else 'NO'}"
          f" ({speed / LINE_BYTES_PER_S:.2f} x line rate)")


if __name__ == "__main__":
    main()
