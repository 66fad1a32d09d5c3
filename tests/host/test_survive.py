"""Capture files survive every way a capture can end, one program per port, and a damaged
capture file is read as far as it can be: real ``fliss capture`` processes on a model board's
pty, stopped by SIGINT, SIGTERM, SIGHUP and SIGKILL."""

import errno
import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from fliss.hdl.registers import defaults
from fliss.host.cli import main
from fliss.host.client import BoardClient
from fliss.host.fileformat import RUNNING, CaptureWriter, read_capture
from fliss.host.stream import HistogramFrame
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene


SHIFT = 2
BINS = 8192 >> SHIFT
SCENE = Scene(detections_per_pulse=0.1, background_hz=2e5)
#: The SIGKILL warning of ``fliss analyze``/``plot`` and of :attr:`Capture.problems`.
NOT_CLOSED = ("its writer never closed it (the capture was killed, or is still running): what "
              "was flushed is read, its counters are missing")


def fliss_capture(model, output, *extra):
    return subprocess.Popen(
        [sys.executable, "-m", "fliss", "capture", "--port", model.path, "--timeout", "2",
         "--integration", "2ms", "--acquisitions", "100000", "-o", str(output), *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_rows(output, process, rows=3, limit_s=60.0):
    """Read the file while the capture writes it until it holds ``rows`` histograms; returns
    how many it held (all of them flushed to the disk)."""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()
        if output.exists():
            try:
                held = len(read_capture(output).histograms)
            except ValueError:          # made, not yet in single-writer mode
                held = 0
            if held >= rows:
                return held
        time.sleep(0.05)
    process.kill()
    pytest.fail(f"the capture wrote fewer than {rows} histograms in {limit_s} s")


def check_rows(capture, model, at_least):
    """Every row is a histogram the board sent, bin for bin, in order, none missing."""
    assert len(capture.histograms) >= at_least
    assert capture.complete.all()
    frames = capture.frames.astype(np.int64)
    assert np.array_equal(frames, frames[0] + np.arange(len(frames)))
    sent = model.sent_histograms(BINS)
    for row, frame in zip(capture.histograms, frames):
        assert np.array_equal(row, sent[frame]), frame


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP])
def test_a_signal_stops_the_board_and_closes_the_file(tmp_path, signum):
    output = tmp_path / "signal.h5"
    with model_board(scene=SCENE) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": SHIFT})
        process = fliss_capture(model, output)
        seen = wait_for_rows(output, process)
        process.send_signal(signum)
        out, err = process.communicate(timeout=30)
        assert not model.running
        capture = read_capture(output)
        check_rows(capture, model, seen)
    assert process.returncode == 128 + signum, err
    name = "" if signum == signal.SIGINT else f" by {signum.name}"
    assert err.strip().splitlines()[-1] == \
        f"fliss: interrupted{name}; acquisition stopped, capture saved"
    assert "Traceback" not in err
    assert capture.attrs["end_reason"] == f"interrupted: {signum.name}"
    assert capture.problems == []
    assert capture.counters["board_end"]["running"] == 0
    assert capture.counters["stream"]["lost_rows"] == 0


@pytest.mark.parametrize("before, readout, signum", [
    ("depth", "histogram", signal.SIGTERM), ("histogram", "depth", signal.SIGINT)])
def test_a_stop_after_frames_of_the_other_readout_loses_nothing(tmp_path, before, readout,
                                                                 signum):
    # The board numbers histograms and depth frames apart, each from reset, and its STATUS
    # `frames` counts both: after 6 frames of one readout, a capture of the other stopped early
    # holds exactly the frames the board made in it, every one complete, none reported lost.
    output = tmp_path / "after.h5"
    with model_board(scene=SCENE) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": SHIFT})
        assert main(["-q", "capture", "--port", model.path, "--timeout", "2", "--readout",
                     before, "--integration", "2ms", "--acquisitions", "6",
                     "-o", str(tmp_path / "before.h5")]) == 0
        # (the first capture's board may have made more than its 6 frames before its STOP: a
        # slow host asks for the stop late)
        made_before = model.status["frames"]
        process = fliss_capture(model, output, "--readout", readout)
        deadline = time.monotonic() + 60
        while process.poll() is None and model.status["frames"] < made_before + 14 and \
                time.monotonic() < deadline:
            time.sleep(0.05)
        process.send_signal(signum)
        out, err = process.communicate(timeout=30)
    assert process.returncode == 128 + signum, err
    capture = read_capture(output)
    made = capture.counters["board_end"]["frames"] - capture.counters["board_start"]["frames"]
    assert made >= 10
    assert len(capture.frames) == made and capture.complete.all()
    frames = capture.frames.astype(np.int64)
    assert np.array_equal(frames, np.arange(made))      # the first of its readout since reset
    assert capture.counters["stream"]["lost_rows"] == 0
    assert ", 0 incomplete histograms, 0 histograms lost\n" in out


def test_after_sigkill_every_flushed_row_is_read_and_the_running_board_is_reported(
        tmp_path, capsys):
    output = tmp_path / "killed.h5"
    with model_board(scene=SCENE) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": SHIFT})
        process = fliss_capture(model, output)
        seen = wait_for_rows(output, process, rows=40)      # past a 32-row gzip chunk
        process.kill()
        process.communicate(timeout=30)
        assert process.returncode == -signal.SIGKILL
        capture = read_capture(output)
        check_rows(capture, model, seen)
        assert capture.attrs["end_reason"] == RUNNING
        assert capture.problems == [NOT_CLOSED]

        # The reader commands: every row, one warning line, no traceback.
        status = main(["analyze", str(output)])
        out, err = capsys.readouterr()
        assert status == 0, err
        assert err == f"fliss: warning: {output}: {NOT_CLOSED}\n"
        assert f"{len(capture.histograms)} complete histograms of " \
               f"{len(capture.histograms)}" in out
        assert main(["plot", str(output), "-o", str(tmp_path / "killed.png")]) == 0
        assert capsys.readouterr().err == f"fliss: warning: {output}: {NOT_CLOSED}\n"

        # The board was left acquiring: the next commands say so, and capture stops it.
        assert model.running
        warning = (f"fliss: warning: the board on {model.path} is acquiring, and sending data "
                   f"that no one records (left running by a capture that was killed?); ")
        assert main(["config", "--port", model.path, "--timeout", "2"]) == 0
        assert capsys.readouterr().err == \
            warning + "`fliss capture` stops it (and starts it again)\n"
        again = tmp_path / "again.h5"
        assert main(["-q", "capture", "--port", model.path, "--timeout", "2",
                     "--integration", "2ms", "--acquisitions", "3", "-o", str(again)]) == 0
        assert capsys.readouterr().err == \
            warning + "this capture stops it and starts it again\n"
        assert not model.running
        assert main(["config", "--port", model.path, "--timeout", "2"]) == 0
        assert capsys.readouterr().err == ""
    assert read_capture(again).attrs["end_reason"] == "completed"


def test_a_second_program_on_the_port_is_refused(tmp_path):
    output = tmp_path / "first.h5"
    with model_board(scene=SCENE) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": SHIFT})
        process = fliss_capture(model, output)
        wait_for_rows(output, process)
        for argv in (["config"], ["capture", "-o", str(tmp_path / "second.h5")]):
            second = subprocess.run([sys.executable, "-m", "fliss", *argv, "--port",
                                     model.path, "--timeout", "2"],
                                    capture_output=True, text=True, timeout=60)
            assert (second.returncode, second.stderr) == (
                1, f"fliss: error: serial port '{model.path}' is busy (is another program "
                   f"using it?)\n")
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=30)
        assert process.returncode == 130, err
        capture = read_capture(output)
        check_rows(capture, model, 3)
    assert capture.counters["link"]["dropped_frames"] == 0
    assert capture.counters["link"]["missing_packets"] == 0
    assert not (tmp_path / "second.h5").exists()


# A damaged file: what can be read is read

def _written(path, rows, flush_s=0.5):
    identity = {"protocol": 1, "gateware_version": "1.0", "registers": 1,
                "clock_hz": 80_000_000, "baud": 12_000_000}
    configuration = dict(defaults(80_000_000), bin_shift=SHIFT)
    writer = CaptureWriter(path, mode="histogram", identity=identity,
                           configuration=configuration, flush_s=flush_s)
    rng = np.random.default_rng(5)
    histograms = rng.poisson(3.0, (rows, BINS)).astype(np.uint32)
    for index, counts in enumerate(histograms):
        writer.add_histogram(HistogramFrame(100 + index, SHIFT, counts, True, 0, 1.0 + index))
    return writer, histograms


def test_a_file_with_an_unreadable_chunk_gives_every_row_before_it(tmp_path, capsys):
    # An older fliss (without single-writer mode) killed mid-write left its last compressed
    # chunk unreadable; the reader keeps the rows before it and says which are left out.
    path = tmp_path / "damaged.h5"
    writer, histograms = _written(path, 70)
    writer.close()
    with h5py.File(path, "r") as f:
        counts = f["histograms/counts"]
        per_chunk = counts.chunks[0]
        kept = (70 // per_chunk) * per_chunk
        last, = [counts.id.get_chunk_info(index) for index in range(counts.id.get_num_chunks())
                 if counts.id.get_chunk_info(index).chunk_offset[0] == kept]
    with open(path, "r+b") as handle:
        handle.seek(last.byte_offset)
        handle.write(bytes(range(256)) * (last.size // 256) + b"\0" * (last.size % 256))
    assert 0 < kept < 70
    capture = read_capture(path)
    assert np.array_equal(capture.histograms, histograms[:kept])
    assert np.array_equal(capture.frames, 100 + np.arange(kept))
    problem, = capture.problems
    assert problem.startswith(f"rows {kept} to 69 of /histograms/counts cannot be read (")
    assert problem.endswith(") and are left out")
    assert main(["analyze", str(path)]) == 0
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith(f"fliss: warning: {path}: rows {kept} to 69")
    assert f"{kept} complete histograms of {kept}" in out


def test_the_writer_flushes_within_its_interval(tmp_path):
    # What a `kill -9` loses: rows added since the last flush, at most flush_s of them. Here a
    # flush after every row (flush_s=0) leaves every row readable while the file is open.
    path = tmp_path / "open.h5"
    writer, histograms = _written(path, 10, flush_s=0.0)
    capture = read_capture(path)
    assert np.array_equal(capture.histograms, histograms)
    assert capture.attrs["end_reason"] == RUNNING
    writer.close("completed")
    capture = read_capture(path)
    assert capture.problems == [] and capture.attrs["end_reason"] == "completed"


# Bad files: one line, never a traceback

def _bad_files(tmp_path):
    (tmp_path / "empty.h5").write_bytes(b"")
    (tmp_path / "text.h5").write_text("not hdf5\n")
    (tmp_path / "folder.h5").mkdir()
    with h5py.File(tmp_path / "claims.h5", "w") as f:
        f.attrs["format"] = "fliss-capture"
        f.attrs["format_version"] = 2
    with h5py.File(tmp_path / "bad-version.h5", "w") as f:
        f.attrs["format"] = "fliss-capture"
        f.attrs["format_version"] = "two"
    with h5py.File(tmp_path / "bad-config.h5", "w") as f:
        f.attrs["format"] = "fliss-capture"
        f.attrs["format_version"] = 2
        f.create_group("identity")
        f.create_group("configuration").attrs["period"] = "eighty"
    with h5py.File(tmp_path / "newer.h5", "w") as f:
        f.attrs["format"] = "fliss-capture"
        f.attrs["format_version"] = 9
    with h5py.File(tmp_path / "other.h5", "w"):
        pass
    return {
        "missing.h5": "no such file: {}",
        "empty.h5": "{} is empty, not a capture file",
        "text.h5": "'{}' is not an HDF5 file (file signature not found), not a capture file",
        "folder.h5": "{} is a folder, not a capture file",
        "claims.h5": "'{}' claims the FLISS capture format but is damaged or not written by "
                     "fliss (no /identity group)",
        "bad-version.h5": "'{}' has format version 'two', not a number: it is damaged or not "
                          "written by fliss",
        "bad-config.h5": "'{}' claims the FLISS capture format but is damaged or not written "
                         "by fliss (invalid literal for int() with base 10: 'eighty')",
        "newer.h5": "'{}' has format version 9, newer than this fliss reads (3); update fliss",
        "other.h5": "'{}' is not a FLISS capture file",
    }


def test_bad_capture_files_are_refused_in_one_line(tmp_path, capsys):
    for name, message in _bad_files(tmp_path).items():
        path = str(tmp_path / name)
        for argv in (["analyze", path], ["plot", path, "-o", str(tmp_path / "p.png")]):
            assert main(argv) == 1, argv
            out, err = capsys.readouterr()
            assert err == f"fliss: error: {message.format(path)}\n", argv
        with pytest.raises(ValueError):
            read_capture(path)
    assert main(["analyze", "/dev/null"]) == 1
    assert capsys.readouterr().err == \
        "fliss: error: /dev/null is not a regular file (a device or a pipe?), not a capture file\n"


# Bad paths for the outputs: refused before the board is touched

def test_unwritable_capture_outputs_are_refused_before_the_board(tmp_path, capsys):
    # --port names no port at all: a refusal about the port would mean the path came second.
    port = str(tmp_path / "no-such-port")
    (tmp_path / "taken.h5").write_bytes(b"")
    cases = [
        (["-o", str(tmp_path)], f"--output: {tmp_path} is a folder; give the name of a file "
                                f"to write"),
        (["-o", str(tmp_path), "--overwrite"], f"--output: {tmp_path} is a folder; give the "
                                               f"name of a file to write"),
        (["-o", "/dev/null", "--overwrite"], "cannot write /dev/null: it is not a regular "
                                             "file (a device or a pipe?); give the name of a "
                                             "file to write"),
        (["-o", str(tmp_path / "none" / "x.h5")], f"cannot write {tmp_path / 'none' / 'x.h5'}:"
                                                  f" no folder {tmp_path / 'none'} (make it "
                                                  f"first)"),
        (["-o", str(tmp_path / "taken.h5")], f"{tmp_path / 'taken.h5'} exists (use "
                                             f"--overwrite to replace it)"),
        (["-o", "/proc/fliss.h5"], None),           # a folder no one may write in
    ]
    if os.geteuid() != 0:                           # root writes in read-only folders
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o555)
        cases.append((["-o", str(locked / "x.h5")], f"cannot write {locked / 'x.h5'}: "
                                                    f"permission denied (in {locked})"))
    for extra, message in cases:
        assert main(["capture", "--port", port, *extra]) == 1, extra
        err = capsys.readouterr().err
        if message is None:
            assert err.startswith("fliss: error: cannot write /proc/fliss.h5: ") and \
                err.count("\n") == 1, err
        else:
            assert err == f"fliss: error: {message}\n", extra
    # Nothing left behind by the checks.
    assert set(os.listdir(tmp_path)) == {"taken.h5"} | ({"locked"} if os.geteuid() else set())


def test_a_full_disk_mid_capture_stops_the_board_and_keeps_the_rows(tmp_path, capsys,
                                                                    monkeypatch):
    output = tmp_path / "full.h5"
    add_frame = CaptureWriter.add_frame      # (every row of every kind of data goes through it)

    def full_after_three(self, frame, **options):
        if self.histograms == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        return add_frame(self, frame, **options)

    monkeypatch.setattr(CaptureWriter, "add_frame", full_after_three)
    with model_board(scene=SCENE) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": SHIFT})
        status = main(["-q", "capture", "--port", model.path, "--timeout", "2",
                       "--integration", "2ms", "--acquisitions", "100", "-o", str(output)])
        assert not model.running
        capture = read_capture(output)
        check_rows(capture, model, 3)
    assert status == 1
    assert capsys.readouterr().err == (
        f"fliss: error: cannot write {output}: no space left on device; the board was "
        f"stopped, and the file holds the 3 histograms written before\n")
    assert len(capture.histograms) == 3
    assert capture.attrs["end_reason"] == f"cannot write {output}: no space left on device"
    assert capture.problems == []
