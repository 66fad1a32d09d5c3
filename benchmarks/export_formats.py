"""Export time and size of a large raw capture: the figures of docs/file-format.md.

Makes a raw capture of ``--events`` synthetic events (10**7 by default: laser cycles at about
one event per ten cycles, every pixel address, uniform TDC codes, 5 % collisions) with
:class:`~fliss.host.fileformat.CaptureWriter` in batches of ``--batch`` events, then exports it
with :func:`fliss.host.formats.export_capture` to PTU and to Photon-HDF5, and prints, for each
file, the seconds, the events per second and the bytes per event, beside the baseline: the
capture file's own write and read (``read_capture``). A histogram capture of ``--rows`` rows of
8192 bins holding as many counts goes to PTU (T3 image mode, one record per count) for
comparison. The exports are read back (ptufile; h5py) and checked event by event.

Usage: python benchmarks/export_formats.py [--events 10000000] [--batch 4096] [--rows 100]
"""

import argparse
import os
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


def synthetic_events(n, seed=1):
    rng = np.random.default_rng(seed)
    events = np.zeros(n, dtype=EVENT_DTYPE)
    events["pulse"] = np.cumsum(rng.geometric(0.1, n) - 1) & 0xFFFFFFFF
    events["timestamp"] = rng.integers(0, 8192, n)
    events["address"] = rng.integers(0, 64, n)
    events["collision"] = rng.random(n) < 0.05
    return events


def timed(function, *args):
    start = time.perf_counter()
    result = function(*args)
    return result, time.perf_counter() - start


def write_raw(path, events, batch):
    registers = dict(defaults(CLOCK_HZ), delay_mode=1, length=6, seed=1)
    with CaptureWriter(str(path), mode="raw", identity=IDENTITY,
                       configuration=registers) as writer:
        for start in range(0, len(events), batch):
            writer.add_events(EventBatch(events[start:start + batch], float(start)))


def synthetic_rows(rows, counts_per_row, seed=2):
    rng = np.random.default_rng(seed)
    return rng.multinomial(counts_per_row, np.full(8192, 1 / 8192), rows).astype(np.uint32)


def write_histograms(path, rows):
    with CaptureWriter(str(path), mode="histogram", identity=IDENTITY,
                       configuration=defaults(CLOCK_HZ)) as writer:
        for i, row in enumerate(rows):
            writer.add_histogram(HistogramFrame(i, 0, row, True, 0, float(i)))


def line(what, seconds, size, n, unit="events"):
    print(f"{what:<34} {seconds:>8.2f} s {n / seconds:>12.3g} {unit}/s "
          f"{size / 1e6:>9.1f} MB {size / n:>7.2f} B/{unit[:-1]}")


def check(capture, folder):
    import ptufile
    with ptufile.PtuFile(folder / "r.ptu") as ptu:
        records = ptu.decode_records()
    photons = records[records["channel"] >= 0]
    assert np.array_equal(photons["dtime"], capture.events["timestamp"])
    assert np.array_equal(photons["channel"], capture.events["address"])
    assert np.array_equal(photons["time"] & 0xFFFFFFFF, capture.events["pulse"])
    with h5py.File(folder / "r.hdf5", "r") as f:
        assert np.array_equal(f["photon_data/nanotimes"][()], capture.events["timestamp"])
        assert np.array_equal(f["photon_data/timestamps"][()] & 0xFFFFFFFF,
                              capture.events["pulse"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--events", type=int, default=10_000_000)
    parser.add_argument("--batch", type=int, default=4096)
    parser.add_argument("--rows", type=int, default=100)
    args = parser.parse_args()
    events = synthetic_events(args.events)
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        print(f"{args.events} events, batches of {args.batch}")
        print(f"{'':<34} {'time':>10} {'rate':>20} {'size':>12} {'per event':>9}")
        _, seconds = timed(write_raw, folder / "r.h5", events, args.batch)
        size = os.path.getsize(folder / "r.h5")
        line("capture file (HDF5) write", seconds, size, args.events)
        capture, seconds = timed(read_capture, folder / "r.h5")
        line("capture file (HDF5) read", seconds, size, args.events)
        for to, out in (("ptu", "r.ptu"), ("photon-hdf5", "r.hdf5")):
            _, seconds = timed(export_capture, capture, folder / out, to)
            line(f"export --to {to}", seconds, os.path.getsize(folder / out), args.events)
        check(capture, folder)
        print("exports read back (ptufile, h5py): every event equal")
        per_row = args.events // args.rows
        rows = synthetic_rows(args.rows, per_row)
        _, seconds = timed(write_histograms, folder / "h.h5", rows)
        histograms = read_capture(folder / "h.h5")
        print(f"\n{args.rows} histograms of 8192 bins, {per_row} counts each")
        line("capture file (HDF5) write", seconds, os.path.getsize(folder / "h.h5"),
             args.rows * per_row, "counts")
        _, seconds = timed(export_capture, histograms, folder / "h.ptu", "ptu")
        line("export --to ptu (T3 image)", seconds, os.path.getsize(folder / "h.ptu"),
             args.rows * per_row, "counts")


if __name__ == "__main__":
    main()
