"""The port disappearing under a command: a model board in a process of its own
(``python -m fliss.sim.boards.model``), killed (SIGKILL: its pty closes, as a USB serial adapter
pulled out) while ``fliss selftest``, ``calibrate``, ``view --port`` and ``capture`` use it.
Each ends with one line that names the port and what was lost, status 1, no traceback; a
capture's file holds every histogram received, as the message counts."""

import os
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from fliss.host.fileformat import read_capture


LOST = "fliss: error: lost the connection to the board on {} ("


class Command:
    """A ``fliss`` process whose stderr is read line by line as it comes."""

    def __init__(self, argv):
        self.process = subprocess.Popen([sys.executable, "-m", "fliss", *argv],
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                        text=True)
        self.lines = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.process.stderr:
            self.lines.append(line.rstrip("\n"))

    def holds(self, path):
        """True once the process has ``path`` open."""
        folder = f"/proc/{self.process.pid}/fd"
        try:
            names = os.listdir(folder)
        except OSError:
            return False
        for name in names:
            try:
                if os.readlink(f"{folder}/{name}") == path:
                    return True
            except OSError:
                pass
        return False

    def wait_for(self, ready, limit_s=60.0):
        deadline = time.monotonic() + limit_s
        while not ready():
            if self.process.poll() is not None or time.monotonic() > deadline:
                self.process.kill()
                pytest.fail(f"never ready: {self.finish()}")
            time.sleep(0.02)

    def finish(self):
        self.process.wait(timeout=60)
        out = self.process.stdout.read()        # (a few lines: never fills the pipe)
        self._reader.join(timeout=10)
        return self.process.returncode, out, self.lines


class ModelProcess:
    """``python -m fliss.sim.boards.model --fine-tdc`` (the fine TDC for calibrate and the
    self-test's loopback), its pty's path in :attr:`path`."""

    def __enter__(self):
        self.process = subprocess.Popen(
            [sys.executable, "-m", "fliss.sim.boards.model", "--fine-tdc"],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        self.path = self.process.stdout.readline().strip()
        assert self.path.startswith("/dev/"), self.path
        return self

    def kill(self):
        self.process.send_signal(signal.SIGKILL)
        self.process.wait(timeout=30)

    def __exit__(self, *exc):
        if self.process.poll() is None:
            self.kill()


def _lost_line(lines, path):
    """The command's last line, checked to be the one error line, with no traceback."""
    assert not any("Traceback" in line for line in lines), lines
    assert [line for line in lines if line.startswith("fliss: error")] == lines[-1:], lines
    line = lines[-1]
    assert line.startswith(LOST.format(path)), line
    return line


@pytest.mark.parametrize("argv, marker", [
    (["selftest"], "[2/5 checks]"),        # past its first check
    (["calibrate"], None),                  # the oscillator's hits or the table
    (["view", "--view-port", "0"], "fliss: view at http://"),
])
def test_a_board_lost_mid_command_is_one_line(argv, marker):
    with ModelProcess() as model:
        command = Command([*argv, "--port", model.path, "--timeout", "2"])
        command.wait_for(lambda: command.holds(model.path) and (
            marker is None or any(line.startswith(marker) for line in command.lines)))
        time.sleep(0.5)
        assert command.process.poll() is None, command.lines
        model.kill()
        status, out, lines = command.finish()
    assert status == 1, lines
    assert re.fullmatch(re.escape(LOST.format(model.path)) + r".+\)", _lost_line(lines, model.path))
    assert "Traceback" not in out


@pytest.mark.parametrize("readout, unit", [("histogram", "histograms"),
                                           ("raw", "events in \\d+ packets")])
def test_a_board_lost_mid_capture_leaves_every_row_received(tmp_path, readout, unit):
    output = tmp_path / f"{readout}.h5"
    amount = ["--duration", "600s"] if readout == "raw" else ["--acquisitions", "100000"]
    with ModelProcess() as model:
        command = Command(["capture", "-q", "--port", model.path, "--timeout", "2", "--readout",
                           readout, "--integration", "2ms", "-o", str(output), *amount])

        def written():
            try:
                capture = read_capture(output)
            except ValueError:
                return False
            return len(capture.frames) >= 5 or len(capture.events) >= 1000
        command.wait_for(written)
        model.kill()
        status, out, lines = command.finish()
    assert status == 1, lines
    line = _lost_line(lines, model.path)
    match = re.fullmatch(re.escape(LOST.format(model.path)) + r".+\); saved what was received "
                         rf"\((\d+) {unit}\) to {re.escape(str(output))}", line)
    assert match, line
    held = int(match.group(1))
    capture = read_capture(output)
    assert capture.problems == []
    assert capture.attrs["end_reason"].startswith("board lost: lost the connection to the "
                                                  f"board on {model.path}")
    if readout == "raw":
        assert len(capture.events) == held >= 1000
    else:
        frames = capture.frames.astype(np.int64)
        assert len(frames) == held >= 5
        assert np.array_equal(frames, frames[0] + np.arange(held))
