"""Export time, size and peak memory of a large raw capture (docs/file-format.md, "Export time,
size and memory").

Makes a raw capture of ``--events`` synthetic events (10**7 by default; 125 000 000 make a
capture file of 1.0 GB, 8 bytes an event: laser cycles at about one event per ten cycles, every
pixel address, uniform TDC codes, 5 % collisions) with :class:`~fliss.host.fileformat.
CaptureWriter` in batches of ``--batch`` events, made and written a million events at a time.
Then, each in a process of its own so that its peak memory (``ru_maxrss``) is its own: the
capture read whole (``read_capture``, the baseline: what ``fliss export`` holds before it
writes anything), and the export (:func:`fliss.host.formats.export_capture`) to PTU and to
Photon-HDF5. Prints, for each, the seconds, the events per second, the file's size and bytes
per event, and the peak memory. The exports are read back (ptufile; h5py) and checked event by
event unless ``--no-check``. A histogram capture of ``--rows`` rows of 8192 bins holding as many
counts goes to PTU (T3 image mode, one record per count) for comparison. Files go in a
temporary folder under ``--folder`` (the system's temporary folder by default), removed at the
end.

Usage: python benchmarks/export_formats.py [--events 10000000] [--batch 4096] [--rows 100]
                                           [--folder DIR] [--no-check]
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

from fliss.hdl.registers import defaults
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.host.formats import export_capture
from fliss.host.stream import EventBatch, HistogramFrame
from fliss.protocol.events import EVENT_DTYPE


CLOCK_HZ = 80_000_000
IDENTITY = {"protocol": 3, "gateware_version": "0.0", "registers": 0, "clock_hz": CLOCK_HZ,
            "baud": 3_000_000}
BLOCK = 1 << 20                         # events made (and checked) at a time


def synthetic_blocks(n, seed=1):
    """The events, ``BLOCK`` at a time: pulses go on from block to block, wrapping at 2**32."""
    rng = np.random.default_rng(seed)
    pulse = 0
    for start in range(0, n, BLOCK):
        size = min(BLOCK, n - start)
        events = np.zeros(size, dtype=EVENT_DTYPE)
        cycles = pulse + np.cumsum(rng.geometric(0.1, size) - 1)
        events["pulse"] = cycles & 0xFFFFFFFF
        events["timestamp"] = rng.integers(0, 8192, size)
        events["address"] = rng.integers(0, 64, size)
        events["collision"] = rng.random(size) < 0.05
        pulse = int(cycles[-1])
        yield events


def write_raw(path, n, batch):
    registers = dict(defaults(CLOCK_HZ), delay_mode=1, length=6, seed=1)
    with CaptureWriter(str(path), mode="raw", identity=IDENTITY,
                       configuration=registers) as writer:
        for block in synthetic_blocks(n):
            for start in range(0, len(block), batch):
                writer.add_events(EventBatch(block[start:start + batch], float(start)))


def synthetic_rows(rows, counts_per_row, seed=2):
    rng = np.random.default_rng(seed)
    return rng.multinomial(counts_per_row, np.full(8192, 1 / 8192), rows).astype(np.uint32)


def write_histograms(path, rows):
    with CaptureWriter(str(path), mode="histogram", identity=IDENTITY,
                       configuration=defaults(CLOCK_HZ)) as writer:
        for i, row in enumerate(rows):
            writer.add_histogram(HistogramFrame(i, 0, row, True, 0, float(i)))


def child(capture_path, to, out):
    """In the measured process: read the capture, export it to ``to`` (``none``: read only);
    prints the seconds of each as JSON."""
    start = time.perf_counter()
    capture = read_capture(capture_path)
    read_s = time.perf_counter() - start
    start = time.perf_counter()
    if to != "none":
        export_capture(capture, out, to)
    print(json.dumps({"read_s": read_s, "export_s": time.perf_counter() - start}))


def measured(capture_path, to, out):
    """(read seconds, export seconds, peak resident bytes) of :func:`child` in a process of
    its own."""
    process = subprocess.Popen([sys.executable, __file__, "--child", str(capture_path), to,
                                str(out)], stdout=subprocess.PIPE, text=True)
    output = process.stdout.read()
    _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    if process.returncode:
        raise SystemExit(f"the {to} export failed (exit {process.returncode})")
    times = json.loads(output)
    return times["read_s"], times["export_s"], usage.ru_maxrss * 1024     # kB on Linux


def line(what, seconds, size, n, peak=None, unit="events"):
    memory = f"{peak / 1e6:>9.0f} MB" if peak is not None else ""
    print(f"{what:<30} {seconds:>8.2f} s {n / seconds:>10.3g} {unit}/s "
          f"{size / 1e6:>9.1f} MB {size / n:>6.2f} B/{unit[:-1]} {memory}")


def check(folder, n):
    """The exports' events against the capture's, ``BLOCK`` at a time."""
    import ptufile
    with ptufile.PtuFile(folder / "r.ptu") as ptu:
        records = ptu.decode_records()
    photons = records[records["channel"] >= 0]
    del records
    with h5py.File(folder / "r.h5", "r") as capture, h5py.File(folder / "r.hdf5", "r") as f:
        events, data = capture["events/events"], f["photon_data"]
        assert len(events) == len(photons) == len(data["nanotimes"]) == n
        for start in range(0, n, BLOCK):
            block, stop = events[start:start + BLOCK], start + BLOCK
            ptu = photons[start:stop]
            assert np.array_equal(ptu["dtime"], block["timestamp"])
            assert np.array_equal(ptu["channel"], block["address"])
            assert np.array_equal(ptu["time"] & 0xFFFFFFFF, block["pulse"])
            assert np.array_equal(data["nanotimes"][start:stop], block["timestamp"])
            assert np.array_equal(data["detectors"][start:stop], block["address"])
            assert np.array_equal(data["timestamps"][start:stop] & 0xFFFFFFFF, block["pulse"])


def main():
    if sys.argv[1:2] == ["--child"]:
        return child(*sys.argv[2:5])
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--events", type=int, default=10_000_000,
                        help="events in the raw capture (125000000: a file of 1.0 GB)")
    parser.add_argument("--batch", type=int, default=4096, help="events per written batch")
    parser.add_argument("--rows", type=int, default=100, help="rows of the histogram capture")
    parser.add_argument("--folder", default=None, help="where the temporary files go")
    parser.add_argument("--no-check", action="store_true",
                        help="do not read the exports back")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(dir=args.folder) as name:
        folder = Path(name)
        print(f"{args.events} events, batches of {args.batch}")
        print(f"{'':<30} {'time':>10} {'rate':>19} {'size':>12} {'per event':>14} "
              f"{'peak memory':>12}")
        start = time.perf_counter()
        write_raw(folder / "r.h5", args.events, args.batch)
        size = os.path.getsize(folder / "r.h5")
        line("capture file (HDF5) write", time.perf_counter() - start, size, args.events)
        read_s, _, peak = measured(folder / "r.h5", "none", "")
        line("capture file (HDF5) read", read_s, size, args.events, peak)
        for to, out in (("ptu", "r.ptu"), ("photon-hdf5", "r.hdf5")):
            _, export_s, peak = measured(folder / "r.h5", to, folder / out)
            line(f"export --to {to}", export_s, os.path.getsize(folder / out), args.events,
                 peak)
        print("peak memory: the whole process, the capture read in included")
        if not args.no_check:
            check(folder, args.events)
            print("exports read back (ptufile, h5py): every event equal")
        per_row = args.events // args.rows
        rows = synthetic_rows(args.rows, per_row)
        start = time.perf_counter()
        write_histograms(folder / "h.h5", rows)
        seconds = time.perf_counter() - start
        histograms = read_capture(folder / "h.h5")
        print(f"\n{args.rows} histograms of 8192 bins, {per_row} counts each")
        line("capture file (HDF5) write", seconds, os.path.getsize(folder / "h.h5"),
             args.rows * per_row, unit="counts")
        start = time.perf_counter()
        export_capture(histograms, folder / "h.ptu", "ptu")
        line("export --to ptu (T3 image)", time.perf_counter() - start,
             os.path.getsize(folder / "h.ptu"), args.rows * per_row, unit="counts")


if __name__ == "__main__":
    main()
