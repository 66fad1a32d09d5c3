"""A disk that fills up during a capture: the capture's folder on a disk of a given capacity
(``os.statvfs`` answers its capacity less the file's size), the writer's own arithmetic
checked, then a whole ``fliss capture`` on a model board stopped by it."""

import errno
import os
import re

import numpy as np
import pytest

import fliss.host.filespace as filespace
from fliss.hdl.registers import defaults
from fliss.host.cli import main
from fliss.host.client import BoardClient
from fliss.host.errors import FileFull
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.host.stream import HistogramFrame
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene


SHIFT = 2
BINS = 8192 >> SHIFT
IDENTITY = {"protocol": 1, "gateware_version": "1.0", "registers": 1, "clock_hz": 80_000_000,
            "baud": 12_000_000}


class _Disk:
    """``os.statvfs`` of a disk that holds ``capacity`` bytes, of which ``path`` takes its
    size."""

    def __init__(self, path, capacity):
        self.path, self.capacity = path, capacity

    def __call__(self, folder):
        used = os.path.getsize(self.path) if os.path.exists(self.path) else 0
        return os.statvfs_result((4096, 1, 0, 0, self.capacity - used, 0, 0, 0, 0, 255))


def test_the_writer_refuses_the_row_that_would_not_fit(tmp_path, monkeypatch):
    # No flush (flush_s huge): the room needed grows by twice each row's 4 * BINS bytes, over
    # the reserve; on a disk with room for 5 rows and a byte (its free space fixed), the sixth
    # is refused, and nothing of it is written.
    path = tmp_path / "full.h5"
    writer = CaptureWriter(path, mode="histogram", identity=IDENTITY,
                           configuration=dict(defaults(80_000_000), bin_shift=SHIFT),
                           flush_s=1e9)
    free = writer._room.reserve + 2 * 5 * 4 * BINS + 1
    monkeypatch.setattr(filespace.os, "statvfs", lambda folder: os.statvfs_result(
        (4096, 1, 0, 0, free, 0, 0, 0, 0, 255)))
    rows = np.random.default_rng(1).poisson(2.0, (6, BINS)).astype(np.uint32)
    for index in range(5):
        assert writer.add_histogram(HistogramFrame(index, SHIFT, rows[index], True, 0, 0.0))
    with pytest.raises(FileFull) as raised:
        writer.add_histogram(HistogramFrame(5, SHIFT, rows[5], True, 0, 0.0))
    assert raised.value.errno == errno.ENOSPC
    assert raised.value.strerror == f"the disk is full ({free} bytes free)"
    writer.close("full", complete=False)
    monkeypatch.undo()
    capture = read_capture(path)
    assert np.array_equal(capture.histograms, rows[:5])
    assert capture.problems == []


def test_a_capture_on_a_disk_that_fills_up_stops_with_every_row(tmp_path, capsys,
                                                                 monkeypatch):
    output = tmp_path / "full.h5"
    monkeypatch.setattr(filespace.os, "statvfs", _Disk(str(output), 1_500_000))
    with model_board(scene=Scene(detections_per_pulse=0.1, background_hz=2e5)) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": SHIFT})
        status = main(["-q", "capture", "--port", model.path, "--timeout", "2",
                       "--integration", "2ms", "--acquisitions", "300", "-o", str(output)])
        assert not model.running
        sent = model.sent_histograms(BINS)
    assert status == 1
    err = capsys.readouterr().err
    match = re.fullmatch(rf"fliss: error: cannot write {re.escape(str(output))}: the disk is "
                         rf"full \((\d+) bytes free\); the board was stopped, and the file "
                         rf"holds the (\d+) histograms written before\n", err)
    assert match, err
    monkeypatch.undo()
    capture = read_capture(output)
    held = int(match.group(2))
    assert held > 0 and len(capture.histograms) == held and capture.complete.all()
    for row, frame in zip(capture.histograms, capture.frames):
        assert np.array_equal(row, sent[frame]), frame
    assert capture.problems == []
    assert os.path.getsize(output) <= 1_500_000
