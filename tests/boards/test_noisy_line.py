"""The noisy line (sim/boards/noisy_line.py) and the host on it: faults counted against an independent
count, a 100-histogram capture at a bit error rate of 1e-4 both ways with no wrong data
accepted, a board reset in the middle of a capture, and the progress output of a capture."""

import argparse
import io
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from fliss.protocol.histograms import decode_chunk
from fliss.protocol.packets import HISTOGRAM_TYPES
from fliss.host.acquisition import capture
from fliss.host.commands.common import Progress
from fliss.host.cli import main
from fliss.host.client import BoardClient
from fliss.host.fileformat import read_capture
from fliss.sim.boards.model import model_board
from fliss.sim.boards.noisy_line import (FaultInjector, LineFaults, NoisyLine, add_line_arguments,
                                         faults_from_args)


SHIFT = 6                      # 128 bins: one chunk per histogram
BINS = 8192 >> SHIFT


def _random_bytes(count, seed=0):
    return np.random.default_rng(seed).integers(0, 256, count, dtype=np.uint8).tobytes()



def _apply_in_pieces(injector, data, seed=1):
    # The same stream, cut into reads of random sizes.
    rng = np.random.default_rng(seed)
    out, stalls, start = [], 0, 0
    while start < len(data):
        end = start + int(rng.integers(1, 3000))
        piece, piece_stalls = injector.apply(data[start:end])
        out.append(piece)
        stalls += len(piece_stalls)
        start = end
    return b"".join(out), stalls


# The injector, against counts made here from what went in and what came out

def test_bit_flips_are_counted_exactly_and_reproducible():
    data = _random_bytes(200_000)
    injector = FaultInjector(LineFaults(bit_error_rate=1e-3), seed=7)
    out, _ = _apply_in_pieces(injector, data)
    assert len(out) == len(data)
    difference = np.frombuffer(out, np.uint8) ^ np.frombuffer(data, np.uint8)
    flipped = int(np.unpackbits(difference).sum())
    assert injector.counts.bits_flipped == flipped
    assert injector.counts.bytes_damaged == np.count_nonzero(difference)
    assert sorted(injector.faulty_offsets) == list(np.flatnonzero(difference))
    bits = 8 * len(data)
    assert abs(flipped - 1e-3 * bits) < 5 * np.sqrt(1e-3 * bits)
    # Reproducible whatever the reads: the same seed in one piece gives the same bytes.
    again, _ = FaultInjector(LineFaults(bit_error_rate=1e-3), seed=7).apply(data)
    assert again == out
    assert FaultInjector(LineFaults(bit_error_rate=1e-3), seed=8).apply(data)[0] != out


def test_dropped_duplicated_bytes_and_stalls_are_counted_exactly():
    # No byte equals any of its 250 neighbours: the output can be read back unambiguously.
    data = (np.arange(100_000) % 251).astype(np.uint8).tobytes()
    faults = LineFaults(drop_rate=1e-3, duplicate_rate=2e-3, stall_rate=1e-3, stall_s=0.0)
    injector = FaultInjector(faults, seed=3)
    out, stalls = _apply_in_pieces(injector, data)
    counts = injector.counts
    # Independent count: walk input and output together.
    faulty = set(injector.faulty_offsets)
    dropped = duplicated = j = 0
    for i, value in enumerate(data):
        if i in faulty and out[j] == value:
            assert out[j + 1] == value
            duplicated += 1
            j += 2
        elif i in faulty:
            dropped += 1
        else:
            assert out[j] == value
            j += 1
    assert j == len(out) == len(data) - dropped + duplicated
    assert (dropped, duplicated) == (counts.bytes_dropped, counts.bytes_duplicated)
    assert dropped > 50 and duplicated > 100
    assert stalls == counts.stalls > 50


def test_bad_rates_are_refused_with_one_line(capsys):
    with pytest.raises(ValueError, match=r"^bit error rate must be from 0 to 1, not -0\.1$"):
        LineFaults(bit_error_rate=-0.1)
    parser = argparse.ArgumentParser()
    add_line_arguments(parser)
    for argv, message in ((["--line-errors=-1e-4"], "--line-errors must be from 0 to 1, "
                                                       "not -0.0001"),
                          (["--line-drop", "2"], "--line-drop must be from 0 to 1, not 2"),
                          (["--line-stall-s", "-1"], "--line-stall-s must be at least 0, not "
                                                     "-1")):
        with pytest.raises(ValueError, match=f"^{message}$"):
            faults_from_args(parser.parse_args(argv))
    assert faults_from_args(parser.parse_args([])) is None
    to_host, to_board = faults_from_args(parser.parse_args(["--line-errors", "1e-4",
                                                            "--line-direction", "to-host"]))
    assert (to_host.bit_error_rate, to_board.active) == (1e-4, False)
    # The command line: one line, exit 1, before anything is built.
    assert main(["board", "--line-errors", "1.5"]) == 1
    assert capsys.readouterr().err == "fliss: error: --line-errors must be from 0 to 1, not 1.5\n"
    process = subprocess.run([sys.executable, "-m", "fliss.sim.boards.model", "--line-errors",
                              "-1"], capture_output=True, text=True, timeout=60)
    assert process.returncode == 2
    assert process.stderr == ("python -m fliss.sim.boards.model: error: --line-errors must be "
                              "from 0 to 1, not -1\n")


# The host on a noisy line

def _damaged_frames(model, injector):
    """Frame numbers of the HISTOGRAM chunks the line damaged on the way to the host."""
    ends = np.array([end for _type, _seq, end in model.frames_out])
    hit = set(np.searchsorted(ends, np.array(injector.faulty_offsets), side="right").tolist())
    chunks = iter(model.sent)
    out = []
    for index, (type, _seq, _end) in enumerate(model.frames_out):
        if type in HISTOGRAM_TYPES:
            payload = next(chunks)[2]
            if index in hit:
                out.append(decode_chunk(type, payload).frame)
    return out


def test_capture_at_1e4_both_ways_accepts_nothing_wrong(tmp_path):
    faults = LineFaults(bit_error_rate=1e-4)
    with model_board() as model, \
            NoisyLine(model.path, to_host=faults, to_board=faults, seed=2) as line:
        with BoardClient(line.path, timeout_s=0.5) as board:
            board.identify()
            # (full chunks: as many bytes, so as many bit errors, as the statistics below expect)
            board.write_registers({"bin_shift": SHIFT, "full_readout": 1})
            result = capture(board, tmp_path / "noisy.h5", integration_s=1e-3,
                             acquisitions=100)
            # The line clean again, every frame the board sent is accounted for by the host.
            line.to_host.faults = line.to_board.faults = LineFaults()
            board.ping()
            decoder = board.decoder.counters
        counts = line.counts()
        damaged = _damaged_frames(model, line.to_host)
        sent = model.sent_histograms(BINS)
    assert result.reason == "completed" and result.complete
    capture_file = read_capture(tmp_path / "noisy.h5")
    link = capture_file.counters["link"]
    frames = [int(frame) for frame in capture_file.frames]
    assert frames == list(range(frames[0], frames[0] + 100))
    # Nothing accepted differs from what the board sent; incomplete rows are zeros.
    for frame, row, complete in zip(frames, capture_file.histograms, capture_file.complete):
        if complete:
            np.testing.assert_array_equal(row, sent[frame])
        else:
            assert not row.any()
    # Every histogram the line damaged is marked incomplete in the file, and every histogram
    # marked incomplete was sent (one chunk each here) and never arrived whole.
    marked = {frame for frame, complete in zip(frames, capture_file.complete) if not complete}
    hit = {frame for frame in damaged if frame in frames}
    assert hit and hit <= marked
    assert len(marked) == result.lost_histograms == capture_file.counters["stream"]["lost_rows"]
    # Every damaged frame was detected and counted: each frame the board sent was either
    # accepted or counted missing (the first one synchronises the decoder).
    assert counts["to_host"]["bits_flipped"] >= 5      # about 25 expected
    assert len(damaged) >= 5
    assert link["dropped_frames"] >= len(damaged) and decoder.missing_packets >= len(damaged)
    assert decoder.packets + decoder.missing_packets + 1 == len(model.frames_out)


def test_commands_on_a_noisy_line_are_retried_and_land():
    faults = LineFaults(bit_error_rate=1e-3)
    with model_board() as model, \
            NoisyLine(model.path, to_host=faults, to_board=faults, seed=5) as line:
        with BoardClient(line.path, timeout_s=0.2, retries=8) as board:
            for value in range(2, 33):
                board.write_registers({"length": value}, current=model.model.settings)
                assert board.read_registers(["length"]) == {"length": value}
            link = board.link_counters()
        status = dict(model.status)
        counts = line.counts()
    assert counts["to_board"]["bits_flipped"] > 0 and counts["to_host"]["bits_flipped"] > 0
    assert link["retransmissions"] > 0 and link["dropped_frames"] > 0
    assert status["bad_crc"] + status["truncated"] + status["bad_length"] > 0
    assert model.model.settings["length"] == 32


def test_board_reset_mid_capture_is_reported_and_data_kept(tmp_path, capsys):
    output = tmp_path / "reset.h5"
    with model_board(reset_after=30) as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": SHIFT})
        status = main(["-q", "capture", "--port", model.path, "--timeout", "2",
                       "--integration", "1ms", "--acquisitions", "100", "-o", str(output)])
        out, err = capsys.readouterr()
        sent = model.sent_histograms(BINS)
        assert model.resets == 1 and not model.running
    assert status == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"fliss: error: the board on {model.path} was reset during the "
                               f"capture: its STATUS (sequence number ")
    assert lines[0].endswith(f"; saved what was received (30 histograms) to {output}")
    capture = read_capture(output)
    assert capture.attrs["end_reason"].startswith("board reset: ")
    assert not capture.attrs["complete"]
    assert list(capture.frames) == list(range(30)) and capture.complete.all()
    for frame, row in zip(capture.frames, capture.histograms):
        np.testing.assert_array_equal(row, sent[frame])


# Progress output

def test_progress_on_a_terminal_and_in_a_file():
    stream = io.StringIO()
    bar = Progress(100, "histograms", stream=stream, interval_s=0.05)
    assert not bar.interactive
    end = time.monotonic() + 0.3
    while time.monotonic() < end:
        bar.update(5, "x")
    bar.update(100, force=True)
    bar.close()
    lines = stream.getvalue().splitlines()
    assert "\r" not in stream.getvalue()
    assert lines == ["[5/100 histograms] x", "[100/100 histograms] x"]
    stream = io.StringIO()
    bar = Progress(10, "histograms", stream=stream, interactive=True)
    bar.update(3, force=True)
    bar.update(10, force=True)
    bar.close()
    assert stream.getvalue().count("\r") == 2 and stream.getvalue().endswith("\n")


def test_capture_with_output_redirected_writes_a_few_lines(tmp_path):
    log = tmp_path / "capture.log"
    with model_board() as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": SHIFT})
        with open(log, "w") as handle:
            process = subprocess.run(
                [sys.executable, "-m", "fliss", "capture", "--port", model.path, "--timeout", "2",
                 "--integration", "20ms", "--acquisitions", "60", "-o", str(tmp_path / "r.h5")],
                stdout=handle, stderr=subprocess.STDOUT, timeout=120)
    text = log.read_text()
    assert process.returncode == 0, text
    assert "\r" not in text
    lines = text.splitlines()
    assert 4 <= len(lines) <= 6
    # (rates per second of the host's clock, which a simulated board lags behind: said so)
    assert re.fullmatch(r"\[60/60 histograms\] [\d.]+ [kM]?events/s \(host clock\)  link: 0 "
                        r"corrupt, 0 lost", lines[0]), lines[0]
    assert lines[1].startswith("saved 60 histograms to ")


def test_kill_stops_the_board_and_saves(tmp_path):
    # `kill` (SIGTERM) in the middle of a capture does what Ctrl-C does.
    output = tmp_path / "killed.h5"
    with model_board() as model:
        with BoardClient(model.path, timeout_s=2.0) as board:
            board.write_registers({"bin_shift": SHIFT})
        process = subprocess.Popen(
            [sys.executable, "-m", "fliss", "capture", "--port", model.path, "--timeout", "2",
             "--integration", "2ms", "--acquisitions", "100000", "-o", str(output)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and model.next_frame < 5:
            time.sleep(0.05)
        time.sleep(0.3)
        process.terminate()
        out, err = process.communicate(timeout=15)
        assert not model.running
    assert process.returncode == 128 + signal.SIGTERM, err
    assert err.strip().splitlines()[-1] == \
        "fliss: interrupted by SIGTERM; acquisition stopped, capture saved"
    capture_file = read_capture(output)
    assert capture_file.attrs["end_reason"] == "interrupted: SIGTERM"
    assert len(capture_file.histograms) >= 3
