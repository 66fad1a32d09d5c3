"""The disk filling up during a capture, for real: ``fliss capture`` processes under a file-size
limit (``ulimit -f``, RLIMIT_FSIZE), one for each readout that writes a growing file. Past the
limit a write fails with EFBIG (SIGXFSZ is ignored): HDF5 would go on writing in its cache and
leave a file no one opens, so the writer refuses the append that would pass it, and the file
closes whole."""

import re
import resource
import subprocess
import sys

import numpy as np
import pytest

from fliss.host.fileformat import read_capture
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene


SCENE = Scene(detections_per_pulse=0.1, background_hz=2e5)

#: readout: (extra flags, file-size limit in bytes, what a row is called in the message)
READOUTS = {
    "histogram": (["--bin-shift", "2", "--acquisitions", "100000"], 1_500_000, "histograms"),
    "raw": (["--duration", "600s"], 600_000, "events"),
    "depth": (["--pixels", "64", "--bin-shift", "3", "--acquisitions", "100000"], 600_000,
              "depth frames"),
}


def _limited(limit):
    def preexec():
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return preexec


@pytest.mark.parametrize("readout", sorted(READOUTS))
def test_a_file_size_limit_stops_the_board_and_keeps_a_whole_file(tmp_path, readout):
    extra, limit, unit = READOUTS[readout]
    output = tmp_path / f"{readout}.h5"
    with model_board(scene=SCENE) as model:
        process = subprocess.run(
            [sys.executable, "-m", "fliss", "-q", "capture", "--port", model.path, "--timeout",
             "2", "--readout", readout, "--integration", "2ms", "-o", str(output), *extra],
            capture_output=True, text=True, timeout=120, preexec_fn=_limited(limit))
        running = model.running
        sent = model.sent_histograms(2048) if readout == "histogram" else None
    assert process.returncode == 1, process.stderr
    assert "Traceback" not in process.stderr
    line, = process.stderr.splitlines()
    pattern = (rf"fliss: error: cannot write {re.escape(str(output))}: the file size limit is "
               rf"reached \(ulimit -f: {limit} bytes\); the board was stopped, and the file "
               rf"holds the (\d+) {unit}( in \d+ packets)? written before")
    match = re.fullmatch(pattern, line)
    assert match, line
    held = int(match.group(1))
    assert held > 0
    assert not running
    assert output.stat().st_size <= limit

    # Read back: the file opens, and holds every row (event) the message counts.
    capture = read_capture(output)
    assert capture.problems == []
    assert capture.attrs["end_reason"] == (f"cannot write {output}: the file size limit is "
                                           f"reached (ulimit -f: {limit} bytes)")
    assert not capture.attrs["complete"]
    if readout == "raw":
        assert len(capture.events) == held
        assert len(capture.batch_times_s) == int(match.group(2).split()[1])
        return
    frames = capture.frames.astype(np.int64)
    assert len(frames) == held and capture.complete.all()
    assert np.array_equal(frames, frames[0] + np.arange(held))
    if readout == "histogram":
        for row, frame in zip(capture.histograms, frames):
            assert np.array_equal(row, sent[frame]), frame
    else:
        assert capture.depth["depth_m"].shape == (held, 64)
