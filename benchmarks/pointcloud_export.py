"""Point cloud exports of a large depth capture: time, size and peak memory per format, beside
the capture read whole (the baseline: what holding the capture in memory costs).

Makes a depth capture of ``--frames`` frames of 64 pixels (760 000 frames make about 1 GB:
float32 position, float64 depth, float32 height and background, a detected flag per pixel, and
the per-frame rows), 70 % of the pixels detected, written straight into the capture's
``/depth`` datasets a block at a time. Then, each in a process of its own, its peak
memory measured from after its imports (Linux's VmHWM, reset through ``/proc/self/clear_refs``):
a process that opens the capture and reads nothing (the floor), the depths read whole (the baseline), and the export to each format
(:func:`fliss.host.pointcloud.export.export_points`, runs of ``--run`` frames). Prints, per
format: seconds, points per second, file size, peak memory, the peak above what the process
held before the work, the size of a run (its arrays as read and its points, every pixel
detected) and the peak above the start against it (the goal: under 2x a run, whatever the
number of runs). For MCAP, the chunks written: the writer keeps an index entry of each in
memory until the file's end (by design: the summary that lets a reader seek), the one part
of an export's memory that grows with the capture. Files go in a temporary folder under
``--folder``.

Usage: python benchmarks/pointcloud_export.py [--frames 100000] [--run 4096] [--folder DIR]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import numpy as np

from fliss.host.kinds.depth import create as create_depth
from fliss.host.pointcloud.export import WRITERS


PIXELS = 64
BLOCK = 65536


def make_capture(path, frames):
    generator = np.random.default_rng(3)
    with h5py.File(path, "w") as f:
        f.attrs["mode"] = "depth"
        create_depth(f, {"pixel_bits": 6, "first_pixel": 0, "bin_shift": 4}, 50e-12)
        group = f["depth"]
        for start in range(0, frames, BLOCK):
            size = min(BLOCK, frames - start)
            stop = start + size
            for name in ("position", "depth_m", "height", "background", "detected", "frame",
                         "shift", "time_s", "complete", "missing_bins"):
                group[name].resize(stop, axis=0)
            detected = generator.random((size, PIXELS)) < 0.7
            position = np.where(detected, generator.uniform(10, 400, (size, PIXELS)), np.nan)
            group["position"][start:stop] = position
            group["depth_m"][start:stop] = position * 16 * 50e-12 * 299792458 / 2
            group["height"][start:stop] = generator.uniform(20, 900, (size, PIXELS))
            group["background"][start:stop] = generator.uniform(0, 30, (size, PIXELS))
            group["detected"][start:stop] = detected
            group["frame"][start:stop] = np.arange(start, stop)
            group["time_s"][start:stop] = 1.7e9 + np.arange(start, stop) * 1e-3
            group["complete"][start:stop] = True


CHILD = """
import json, sys, time
import h5py, numpy as np
from fliss.host.pointcloud.export import export_points
from fliss.host.pointcloud.geometry import PAPER_SENSOR
capture, output, what, run = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
def memory(field):
    with open("/proc/self/status") as status:
        return next(int(line.split()[1]) * 1024 for line in status if line.startswith(field))
# The writers' libraries imported before the measure: their code is not the export's data
import laspy, mcap.writer, foxglove_schemas_protobuf.PointCloud_pb2  # noqa: E401, F401
# The peak from here on: Linux resets a process's peak resident size (VmHWM) on a 5 written
# to its clear_refs, so that the imports' own peak does not hide the work's
with open("/proc/self/clear_refs", "w") as clear:
    clear.write("5")
before = memory("VmRSS:")
start = time.perf_counter()
points = 0
if what == "floor":
    with h5py.File(capture, "r") as f:
        pass
elif what == "baseline":
    with h5py.File(capture, "r") as f:
        arrays = {n: f["depth"][n][()] for n in ("depth_m", "detected", "height", "background")}
        points = int(arrays["detected"].sum())
else:
    points = export_points(capture, output, what, PAPER_SENSOR, run_frames=run).points
print(json.dumps({"seconds": time.perf_counter() - start, "points": points,
                  "peak": memory("VmHWM:"), "before": before}))
"""


def mcap_chunks(path):
    # The chunks of an MCAP file, from its summary's statistics
    from mcap.reader import make_reader

    with open(path, "rb") as stream:
        return make_reader(stream).get_summary().statistics.chunk_count


def chunk_index_bytes(count=1000):
    # What one of the writer's chunk index entries costs in memory: ``count`` of them made as
    # the writer makes them (a dict of one channel's message index offset), through tracemalloc
    import tracemalloc

    from mcap.records import ChunkIndex

    tracemalloc.start()
    entries = [ChunkIndex(message_start_time=2**60 + n, message_end_time=2**60 + n,
                          chunk_start_offset=2**30 + n, chunk_length=2**20 + n,
                          message_index_offsets={1: 2**31 + n}, message_index_length=2**14 + n,
                          compression="zstd", compressed_size=2**19 + n,
                          uncompressed_size=2**20 + n) for n in range(count)]
    size = tracemalloc.get_traced_memory()[0] / len(entries)
    tracemalloc.stop()
    return size


def child(capture, output, what, run):
    result = subprocess.run([sys.executable, "-c", CHILD, str(capture), str(output), what,
                             str(run)], capture_output=True, text=True, check=True)
    return json.loads(result.stdout)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=100_000)
    parser.add_argument("--run", type=int, default=4096)
    parser.add_argument("--folder", default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(dir=args.folder) as folder:
        folder = Path(folder)
        capture = folder / "depth.h5"
        start = time.perf_counter()
        make_capture(capture, args.frames)
        size = os.path.getsize(capture)
        print(f"depth capture: {args.frames} frames of {PIXELS} pixels, {size / 1e6:.1f} MB, "
              f"made in {time.perf_counter() - start:.1f} s")
        # A run's arrays as the exporter reads them: depth (8 bytes), detected (1), height,
        # background (4 each) and the complete flag per frame, and its points (36 bytes each)
        run_bytes = args.run * (PIXELS * (8 + 1 + 4 + 4 + 36) + 1 + 4 + 8)
        print(f"a run: {args.run} frames, {run_bytes / 1e6:.1f} MB of arrays and points")
        floor_run = child(capture, None, "floor", args.run)
        floor = floor_run["peak"]
        runs = -(-args.frames // args.run)
        print(f"{runs} runs; the goal: a peak under 2x a run above the start, in every format")
        print(f"{'what':<10} {'seconds':>8} {'points/s':>10} {'size MB':>8} {'peak MB':>8} "
              f"{'above start':>12} {'run MB':>7} {'/ run':>6}")
        print(f"{'floor':<10} {'':>8} {'':>10} {'':>8} {floor / 1e6:>8.1f}")
        chunks = None
        for what in ("baseline", *WRITERS):
            output = folder / f"points.{what}"
            figures = child(capture, output, what, args.run)
            written = os.path.getsize(output) / 1e6 if output.exists() else float("nan")
            above = figures["peak"] - figures["before"]
            print(f"{what:<10} {figures['seconds']:>8.2f} "
                  f"{figures['points'] / figures['seconds']:>10.3g} {written:>8.1f} "
                  f"{figures['peak'] / 1e6:>8.1f} {above / 1e6:>10.1f}MB "
                  f"{run_bytes / 1e6:>7.1f} {above / run_bytes:>6.2f}")
            if what == "mcap":
                chunks = mcap_chunks(output)
            if output.exists():
                output.unlink()
        if chunks is not None:
            entry = chunk_index_bytes()
            print(f"mcap: {chunks} chunks, an index entry each held by the writer to the end: "
                  f"{chunks * entry / 1e6:.2f} MB ({entry:.0f} bytes an entry)")


if __name__ == "__main__":
    main()
