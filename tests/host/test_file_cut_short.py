"""A capture file removed or cut short while a command reads or shows it: ``fliss view FILE``
(a real process: the view read the file whole when it started, so it says what happened in one
warning line and goes on), and a file cut short between its opening and its reading
(``fliss export``, ``analyze``: one line, status 1, nothing written)."""

import os
import signal
import subprocess
import sys
import threading
import time
import urllib.request

import numpy as np
import pytest

import fliss.host.fileformat as fileformat
from fliss.hdl.registers import defaults
from fliss.host.cli import main
from fliss.host.fileformat import CaptureWriter
from fliss.host.stream import HistogramFrame


SHIFT = 2
BINS = 8192 >> SHIFT


def _capture(path, rows=40):
    identity = {"protocol": 1, "gateware_version": "1.0", "registers": 1,
                "clock_hz": 80_000_000, "baud": 12_000_000}
    writer = CaptureWriter(path, mode="histogram", identity=identity,
                           configuration=dict(defaults(80_000_000), bin_shift=SHIFT))
    rng = np.random.default_rng(3)
    for index in range(rows):
        counts = rng.poisson(2.0, BINS).astype(np.uint32)
        writer.add_histogram(HistogramFrame(index, SHIFT, counts, True, 0, 0.01 * index))
    writer.close()


@pytest.mark.parametrize("fault", ["removed", "cut short"])
def test_a_file_removed_or_cut_short_while_shown_is_said_once(tmp_path, fault):
    path = tmp_path / "shown.h5"
    _capture(path)
    size = path.stat().st_size
    process = subprocess.Popen([sys.executable, "-m", "fliss", "view", str(path), "--loop",
                                "--view-port", "0"], stderr=subprocess.PIPE, text=True)
    try:
        lines = []
        reader = threading.Thread(target=lambda: lines.extend(
            line.rstrip("\n") for line in process.stderr), daemon=True)
        reader.start()
        deadline = time.monotonic() + 60
        while not any(line.startswith("fliss: view at ") for line in lines):
            assert process.poll() is None and time.monotonic() < deadline, lines
            time.sleep(0.05)
        url = next(line for line in lines if line.startswith("fliss: view at ")).split()[3]
        if fault == "removed":
            path.unlink()
            what = "was removed"
        else:
            os.truncate(path, size // 2)
            what = f"was cut short (from {size} to {size // 2} bytes)"
        warning = (f"fliss: warning: {path} {what} while shown; the view goes on with the capture "
                   f"as it was read when it started")
        while warning not in lines:
            assert process.poll() is None and time.monotonic() < deadline, lines
            time.sleep(0.05)
        time.sleep(0.5)
        assert process.poll() is None, lines
        with urllib.request.urlopen(url, timeout=30) as page:      # the page is still served
            assert page.status == 200
        process.send_signal(signal.SIGINT)
        assert process.wait(timeout=60) == 0
    finally:
        if process.poll() is None:       # (a failure above: no process left behind)
            process.kill()
    reader.join(timeout=10)
    assert lines.count(warning) == 1
    assert lines[-1] == "fliss: view stopped"
    assert not any("Traceback" in line or line.startswith("fliss: error") for line in lines)


@pytest.mark.parametrize("argv", [["export", "--to", "ptu", "-o", "{out}"], ["analyze"]])
@pytest.mark.parametrize("fraction", [0, 0.5])
def test_a_file_cut_short_while_read_is_refused_in_one_line(tmp_path, capsys, monkeypatch,
                                                            argv, fraction):
    # Another program cuts the file short between its opening and its reading: HDF5 then
    # raises from inside h5py, or reads garbage (or zeros past the end) without a word.
    path = tmp_path / "cut.h5"
    out = tmp_path / "out.ptu"
    _capture(path)
    size = path.stat().st_size
    cut = int(size * fraction)
    opened = fileformat._open

    def open_then_cut(name):
        f = opened(name)
        os.truncate(name, cut)
        return f

    monkeypatch.setattr(fileformat, "_open", open_then_cut)
    command = [argv[0], str(path), *(arg.format(out=out) for arg in argv[1:])]
    assert main(command) == 1
    assert capsys.readouterr().err == (
        f"fliss: error: '{path}' was cut short while it was read (from {size} to {cut} "
        f"bytes): nothing of it is used\n")
    assert not out.exists()
