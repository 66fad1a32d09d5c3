"""A capture whose writer is slower than the board: the data the host has read and not yet
stored stay within a bound (the rest wait in the port, where the model board waits for room),
and every frame the board made is a row of the file or counted; a link whose queue is full
drops what a command reads past it and counts it, frame for frame."""

import os
import pty
import time
import tty

import numpy as np

from fliss.host import acquisition
from fliss.host.acquisition import capture
from fliss.host.client import BoardClient
from fliss.host.commands.capture import report
from fliss.protocol.packets import HISTOGRAM_TYPES
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.sim.boards.model import BACKLOG_BYTES, model_board
from fliss.sim.scene import Scene


SHIFT = 3
BINS = 8192 >> SHIFT
#: A cheap scene (few photons, 10 kHz pulses) that the model runs near real time, and full
#: histogram chunks: each frame 2 bytes a bin on the wire, so the port holds few of them.
SCENE = Scene(detections_per_pulse=0.05, background_hz=1e4)
SETTINGS = {"bin_shift": SHIFT, "period": 10_000, "full_readout": 1}
WRITE_S = 0.02      # the slow writer: 50 rows a second
FRAMES = 120


def _pty_capacity():
    """Bytes a pty takes before its writer must wait (measured: the kernel's buffer)."""
    master, slave = pty.openpty()
    try:
        tty.setraw(slave)
        os.set_blocking(master, False)
        written = 0
        try:
            while True:
                written += os.write(master, bytes(4096))
        except BlockingIOError:
            return written
    finally:
        os.close(master)
        os.close(slave)


def test_a_slow_writer_keeps_the_queue_bounded_and_every_frame(tmp_path, monkeypatch):
    samples = []        # (items queued, frames the board made, rows stored) at each write
    add_frame = CaptureWriter.add_frame

    def slow_add_frame(self, frame, **options):
        time.sleep(WRITE_S)
        samples.append((client.queued, model.status["frames"], self.histograms))
        return add_frame(self, frame, **options)

    monkeypatch.setattr(CaptureWriter, "add_frame", slow_add_frame)
    # (a heartbeat ten times a second: each reads past the data to find its reply)
    monkeypatch.setattr(acquisition, "HEARTBEAT_S", 0.1)
    with model_board(scene=SCENE) as model:
        with BoardClient(model.path, timeout_s=5.0) as client:
            client.write_registers(SETTINGS)
            result = capture(client, str(tmp_path / "slow.h5"), integration_s=1e-3,
                             acquisitions=FRAMES)
        sent = model.sent_histograms(BINS, whole=True)
        # (a histogram's bytes on the wire, from the board's record of the frames it sent)
        ends = [0] + [end for _, _, end in model.frames_out]
        data = sum(b - a for a, b, (kind, _, _) in zip(ends, ends[1:], model.frames_out)
                   if kind in HISTOGRAM_TYPES)
        frame_bytes = data / len(sent)
    assert result.reason == "completed"
    # What the board can have made beyond what the writer has taken, in bytes: what it
    # holds back (the pty's buffer, the model's backlog and one block of frames), and what
    # the host has read: at most two reads of the pty (a read and what came during it), or,
    # for a command, everything the board held back when its reply was queued behind it.
    pty_bytes, block = _pty_capacity(), 2 * frame_bytes
    held = pty_bytes + BACKLOG_BYTES + block
    # That is about 50 frames here; the bound takes twice it (the kernel's line discipline
    # holds more than the pty's buffer measured alone), against hundreds more each second
    # when the host reads all it can (heartbeats read on as long as the board sends).
    bound = 2 * int((held + max(2 * pty_bytes, held)) / frame_bytes)
    queued = max(sample[0] for sample in samples)
    ahead = max(made - stored for _, made, stored in samples)
    # (the board makes frames faster than this writer stores them: else nothing is tested)
    assert len(sent) >= FRAMES and ahead > 10
    assert queued <= bound, (queued, bound)
    assert ahead <= bound, (ahead, bound)
    # Every frame the board made: a row (all of them arrived), or after the last one asked for
    file = read_capture(tmp_path / "slow.h5")
    made = result.status_end["frames"] - result.status_start["frames"]
    stream = file.counters["stream"]
    assert len(file.frames) == FRAMES and file.complete.all()
    assert made == len(file.frames) + stream["discarded_frames"]
    assert stream["queue_dropped_frames"] == 0 and stream["lost_rows"] == 0
    for row, number in enumerate(file.frames.tolist()):
        assert np.array_equal(file.histograms[row], sent[number])


def test_a_full_queue_drops_what_a_command_reads_past_it_and_counts_it():
    with model_board(scene=SCENE) as model:
        limit = 5 * 4 * BINS          # five histograms' counts (uint32)
        with BoardClient(model.path, timeout_s=5.0, queue_limit=limit) as client:
            client.write_registers({**SETTINGS, "integration": 100_000})   # 1 ms
            client.start()
            peak = 0
            end = time.monotonic() + 1.5
            while time.monotonic() < end:
                client.status()            # reads past the data to find its reply
                peak = max(peak, client.queued)
            client.stop()
            taken = client.settle()
            counters = client.assembler.counters
        sent = model.sent_histograms(BINS, whole=True)
    assert peak <= 5
    frames = [item.frame for item in taken]
    dropped = counters.queue_dropped_frames
    assert dropped > 0 and counters.queue_peak_bytes <= limit
    # every frame the board sent: taken, or dropped and counted
    assert len(frames) + dropped == len(sent) == counters.frames
    assert set(frames) <= set(sent)
    for item in taken:
        assert np.array_equal(item.counts, sent[item.frame])


def test_a_capture_whose_queue_overflows_marks_the_rows_lost(tmp_path, monkeypatch, capsys):
    # A queue of two histograms behind a slow writer: a read of the port brings more, the
    # rest is dropped and counted, and each dropped frame within those asked for is a row
    # marked lost
    add_frame = CaptureWriter.add_frame

    def slow_add_frame(self, frame, **options):
        time.sleep(WRITE_S)
        return add_frame(self, frame, **options)

    monkeypatch.setattr(CaptureWriter, "add_frame", slow_add_frame)
    with model_board(scene=SCENE) as model:
        with BoardClient(model.path, timeout_s=5.0, queue_limit=2 * 4 * BINS) as client:
            client.write_registers(SETTINGS)
            result = capture(client, str(tmp_path / "q.h5"), integration_s=1e-3,
                             acquisitions=FRAMES // 2)
        sent = model.sent_histograms(BINS, whole=True)
    file = read_capture(tmp_path / "q.h5")
    stream = file.counters["stream"]
    made = result.status_end["frames"] - result.status_start["frames"]
    lost = ~file.complete
    dropped = stream["queue_dropped_frames"]
    assert dropped > 0 and np.count_nonzero(lost) == stream["lost_rows"] > 0
    # every frame made: a row that arrived, one after the last asked for, or dropped
    arrived = len(file.frames) - stream["lost_rows"]
    assert made == len(sent) == arrived + stream["discarded_frames"] + dropped
    for row in np.flatnonzero(~lost):
        assert np.array_equal(file.histograms[row], sent[int(file.frames[row])])
    assert not file.histograms[lost].any()
    # fliss capture says it in one line
    assert report(result, quiet=True) == 0
    assert capsys.readouterr().err == (
        f"fliss: warning: {dropped} frames and 0 events dropped on the host, whose queue of "
        f"data not yet written was full (counted in the file; the frames' rows are marked "
        f"lost)\n")
