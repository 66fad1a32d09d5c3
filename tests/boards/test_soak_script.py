"""benchmarks/soak.py in its shortened form on the model board: its table and its verdicts
against the capture files it leaves (read here with ``read_capture``), the frame counts against
the board time asked for, the raw phase's drops against what the link carries; and its
verdicts on made-up figures that must fail (memory growing, a frame nobody counted)."""

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from fliss.host.fileformat import Capture, read_capture
from fliss.protocol.events import link_events_per_s


_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "soak.py"
_SPEC = importlib.util.spec_from_file_location("soak", _PATH)
soak = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(soak)

MINUTES = 0.01          # 0.6 s of board time a phase: 600 frames of 1 ms
TARGET_S = MINUTES * 60
ROW = re.compile(r"^\s*([\d.]+)\s+([\d.]+)\s+(histogram|raw|depth)\s+([\d.]+)\s+([\d.]+)\s+"
                 r"(\d+|-)$")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("soak")
    done = subprocess.run([sys.executable, str(_PATH), "--minutes", str(MINUTES),
                           "--sample-s", "0.25", "--folder", str(folder)],
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    return folder, done.stdout.splitlines()


def _line(lines, prefix):
    found = [line for line in lines if line.startswith(prefix)]
    assert len(found) == 1, (prefix, lines)
    return found[0]


# (a real-time run of three captures: make test-long)
@pytest.mark.long
@pytest.mark.parametrize("phase", soak.PHASES)
def test_the_summary_and_counters_are_the_files(run, phase):
    folder, lines = run
    path = folder / f"soak-model-{phase}.h5"
    capture = read_capture(path)
    assert capture.problems == []
    kept = len(capture.events) if phase == "raw" else len(capture.frames)
    unit = "events" if phase == "raw" else "frames"
    summary = _line(lines, f"phase {phase}: file ")
    assert f"file {os.path.getsize(path) / 1e6:.3f} MB, {kept} {unit};" in summary
    assert set(capture.counters) == {"board_start", "board_end", "link", "stream"}
    for group, counters in capture.counters.items():
        printed = _line(lines, f"phase {phase}: counters {group}: ")
        values = dict(item.split("=") for item in printed.split(": ", 2)[2].split())
        assert values == {name: str(value) for name, value in counters.items()}
    # The table: this phase's rows, in order, never more in the file than at the end
    rows = [ROW.match(line).groups() for line in lines if ROW.match(line)
            and ROW.match(line).group(3) == phase]
    assert len(rows) >= 3
    board_s = [float(r[1]) for r in rows]
    counts = [int(r[5]) for r in rows if r[5] != "-"]
    assert board_s == sorted(board_s) and counts == sorted(counts)
    assert counts[-1] == kept
    rss = [float(r[3]) for r in rows if r[5] != "-"]
    assert f"max {max(rss):.1f} MB" in summary


# (a real-time run of three captures: make test-long)
@pytest.mark.long
@pytest.mark.parametrize("phase", ["histogram", "depth"])
def test_a_framed_phase_keeps_every_frame_of_the_board_time_asked_for(run, phase):
    folder, lines = run
    capture = read_capture(folder / f"soak-model-{phase}.h5")
    assert capture.attrs["end_reason"] == "completed"
    assert len(capture.frames) == round(TARGET_S / 1e-3)
    frames = capture.frames.astype(np.int64)
    assert np.array_equal(frames, np.arange(len(frames)))
    assert capture.complete.all()
    start, end = capture.counters["board_start"], capture.counters["board_end"]
    made = end["frames"] - start["frames"]
    # every frame the board made is in the file or was made after the last one asked for
    assert made == len(frames) + capture.counters["stream"]["discarded_frames"]
    drops = [name for name in soak.BOARD_LOSSES if end[name] != start[name]]
    assert drops == []
    assert "verdict " + phase + " losses: nothing lost (" in \
        _line(lines, f"verdict {phase} losses: ")
    # (the memory verdict's word only: a host slower than the model queues frames, RSS grows)
    assert _line(lines, f"verdict {phase} memory: ").split(": ")[1].split()[0] in \
        ("flat", "unknown", "GROWING")


# (a real-time run of three captures: make test-long)
@pytest.mark.long
def test_the_raw_phase_fills_the_link_and_counts_every_drop(run):
    folder, lines = run
    capture = read_capture(folder / "soak-model-raw.h5")
    assert capture.attrs["end_reason"] == "interrupted: SIGINT"
    start, end = capture.counters["board_start"], capture.counters["board_end"]
    accepted = end["events"] - start["events"]
    dropped = end["dropped_fifo"] - start["dropped_fifo"]
    # The board time from its pulses, at the pulse rate of the histogram phase (the same
    # registers: frames of 1 ms, so pulses per second = pulses / frames x 1000)
    framed = read_capture(folder / "soak-model-histogram.h5").counters
    pulse_hz = framed["board_end"]["pulses"] / (framed["board_end"]["frames"] * 1e-3)
    board_s = end["pulses"] / pulse_hz
    assert board_s >= TARGET_S * 0.98
    # what the link carries in the board time, in full packets of events: the rest dropped
    carried = link_events_per_s(soak.MODEL_BAUD) * board_s
    assert abs(len(capture.events) - carried) <= 0.02 * carried + 2 * 64
    assert dropped > 0 and accepted == len(capture.events) + dropped
    assert capture.counters["stream"]["events"] == len(capture.events)
    verdict = _line(lines, "verdict raw losses: ")
    assert verdict.startswith("verdict raw losses: every loss counted (")
    assert f"{len(capture.events)} + {dropped} = {accepted} == {accepted}" in verdict


def test_the_memory_verdict_sees_growth_and_too_few_samples():
    def samples(rss):
        return [soak.Sample(i, 60.0 * i, mb, 0.0, i) for i, mb in enumerate(rss)]
    # 1 MB a board-minute for ten minutes: 60 MB an hour
    assert soak.memory_verdict(samples(70 + np.arange(11.0)))[0] == "GROWING"
    assert soak.memory_verdict(samples(70 + 0.1 * np.arange(11.0)))[0] == "flat"
    assert soak.memory_verdict(samples([70.0, 71.0, 72.0]))[0] == "unknown"


def _capture(frames, made, discarded=0, dropped=0):
    board = dict.fromkeys(soak.BOARD_LOSSES, 0)
    start = {**board, "frames": 0, "events": 0, "pulses": 0}
    end = {**board, "frames": made, "events": 0, "pulses": made * 1000,
           "dropped_histogram": dropped}
    return Capture(path="x.h5", attrs={}, identity={}, configuration={}, histograms=None,
                   frames=np.arange(frames, dtype=np.uint32), shifts=np.zeros(frames),
                   times_s=np.zeros(frames),
                   complete=np.ones(frames, bool), events=np.zeros(0), batch_times_s=None,
                   counters={"board_start": start, "board_end": end,
                             "stream": {"discarded_frames": discarded}}, problems=[])


def test_the_loss_verdict_refuses_a_frame_nobody_counted():
    assert soak.loss_verdict("histogram", _capture(10, 12, discarded=2))[0] == "nothing lost"
    assert soak.loss_verdict("histogram", _capture(10, 12, discarded=1))[0] == "UNACCOUNTED"
    assert soak.loss_verdict("histogram", _capture(10, 12, discarded=2, dropped=5))[0] == \
        "every loss counted"
    no_counters = _capture(10, 12)
    no_counters.counters = {}
    assert soak.loss_verdict("histogram", no_counters)[0] == "unknown"
