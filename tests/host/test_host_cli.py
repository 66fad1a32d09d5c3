"""The ``fliss`` host commands through a real pty, with the Python model board behind it."""

import errno
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import serial

import fliss as fliss_package
from fliss.hdl.protocol import PacketType, PROTOCOL_VERSION
from fliss.hdl.registers import BY_NAME, defaults
from fliss.host.cli import main
from fliss.host.client import BoardClient
from fliss.host.fileformat import read_capture
from fliss.sim.boards.model import model_board, scene_for
from fliss.sim.scene import Scene, Simulation, time_of_flight


CLOCK_HZ = 80_000_000
INTEGRATION = 160_000          # 2 ms
SHIFT = 2
SCENE = Scene(detections_per_pulse=0.1, background_hz=2e5)


def fliss(capsys, *argv):
    argv = list(argv)
    if "--port" in argv and "--timeout" not in argv:
        argv += ["--timeout", "2"]      # generous: the shared test machine may be busy
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out, err


def reference_blocks(settings, seed, blocks, integration=INTEGRATION):
    """Events of each block of ``integration`` clock cycles, straight from the scene simulator
    (the laser cycles whose TDC start falls in the block), with the gate applied."""
    simulation = Simulation(scene_for(settings, SCENE, clock_hz=CLOCK_HZ), seed=seed)
    out = []
    for block in range(blocks):
        end = (block + 1) * integration
        pieces = []
        while simulation.next_start_cycle < end:
            pieces.append(simulation.step(until_cycle=end).events)
        events = np.concatenate(pieces)
        stamps = events["timestamp"]
        out.append(events[(stamps >= settings["gate_start"]) & (stamps <= settings["gate_end"])])
    return out


def histogram_of(events, shift):
    bins = 8192 >> shift
    return np.bincount(events["timestamp"].astype(np.int64) >> shift, minlength=bins)


@pytest.fixture
def model():
    with model_board(scene=SCENE) as board:
        yield board


# config

def test_config_round_trip(model, capsys):
    status, out, err = fliss(capsys, "config", "--port", model.path, "--prf", "500kHz",
                             "--mode", "masked", "--mask-width", "5", "--pulse-width", "25ns",
                             "--aggressor", "on", "--aggressor-offset", "100ns",
                             "--integration", "5ms", "--gate-end", "100ns", "--bin-shift", "2",
                             "--readout", "raw", "--grid", "--seed", "0x2b")
    assert status == 0, err
    # The new bin shift sets the depth threshold: 2048 bins, 2500 cycles of 2 µs in 5 ms, so
    # mu = 4 x 2500 / 2048 = 4.88 counts in a 4-bin window; of 512 windows, P(X >= k) <= 2e-5
    # at k = 17 (P(X >= 16) = 5.3e-5, P(X >= 17) = 1.5e-5): a height of 17 - 4.88, 13.
    expected = dict(defaults(CLOCK_HZ), period=160, delay_mode=2, mask_width=5, pulse_width=2,
                    aggressor=1, aggressor_offset=8, integration=400_000, gate_end=2000,
                    bin_shift=2, acquisition=1, grid=1, seed=0x2b, depth_threshold=13)
    assert model.model.settings == expected
    with BoardClient(model.path, timeout_s=2.0) as board:
        assert board.read_registers() == expected
    # Shown again without settings, with units.
    status, out, err = fliss(capsys, "config", "--port", model.path)
    assert status == 0
    lines = {line.split()[0]: line for line in out.splitlines()[2:]}
    assert "160 cycles" in lines["period"] and "500 kHz" in lines["period"]
    assert "5 ms" in lines["integration"]
    assert "masked" in lines["delay_mode"]
    assert len(lines) == len(expected)


@pytest.mark.parametrize("argv, message", [
    (["--length", "40"], "--length 40: takes values from 2 to 32 bits"),
    (["--mask-width", "17"], "--mask-width 17: takes values from 1 to 16 bits"),
    (["--seed", "0"], "--seed 0: takes values from 1 to 4294967295"),
    # 2 µs is 160 cycles of 12.5 ns; the default period is 80 cycles (1 MHz).
    (["--pulse-width", "2us"], "--pulse-width (2 µs, 160 cycles) must be shorter than --prf "
                               "(1 µs, 80 cycles)"),
    (["--prf", "fast"], "--prf fast: cannot read 'fast' as a frequency (for example 80MHz, 1kHz "
                        "or 1e6Hz)"),
    (["--integration", "1ps"], "--integration 1ps: shorter than one clock cycle (12.5 ns)"),
    (["--integration", "10"], "--integration 10: give a unit: 10ms, or 800cycles"),
    # A negative value is the option's value, refused by its check (not argparse's "expected
    # one argument").
    (["--integration", "-5ms"], "--integration -5ms: time must be positive, not '-5ms'"),
    (["--aggressor-offset", "-.5us"],
     "--aggressor-offset -.5us: time must be positive, not '-.5us'"),
    # A frequency too: 1 would be 1 Hz, a period of 80 000 000 cycles.
    (["--prf", "1"], "--prf 1: give a unit: 80MHz, 1kHz or 1e6Hz"),
    (["--aggressor-prf", "1e6"], "--aggressor-prf 1e6: give a unit: 80MHz, 1kHz or 1e6Hz"),
    (["--mask-width", "six"], "--mask-width six: expected a whole number (0x for hex)"),
    (["--prf", "1MHz", "--period-cycles", "80"],
     "--prf and --period-cycles both set period: give one of them"),
    # Sensor TDC codes of 50 ps: 200 ns is 4000 codes, 100 ns 2000.
    (["--gate-start", "200ns", "--gate-end", "100ns"],
     "--gate-start (200 ns, 4000 codes) must not be after --gate-end (100 ns, 2000 codes)"),
    (["--gate-end", "1us"], "--gate-end 1us: takes values from 0 codes (0 s) to 8191 codes "
                            "(409.6 ns), not 20000 codes (1 µs)"),
])
def test_config_user_errors(model, capsys, argv, message):
    status, out, err = fliss(capsys, "config", "--port", model.path, *argv)
    assert status == 1
    assert err == f"fliss: error: {message}\n"
    assert model.model.settings == defaults(CLOCK_HZ)
    assert model.model.refused == 0


def test_version_mismatch(capsys):
    with model_board(protocol_version=7) as board:
        status, out, err = fliss(capsys, "config", "--port", board.path)
    assert status == 1
    assert err == (f"fliss: error: the board speaks protocol version 7, this fliss speaks "
                   f"version {PROTOCOL_VERSION}: update the host tool\n")


def test_older_gateware_is_one_warning_line(capsys):
    with model_board(gateware_version="0.0.9") as board:
        status, out, err = fliss(capsys, "config", "--port", board.path)
    assert status == 0
    assert err == (f"fliss: warning: the board runs gateware 0.0.9, this fliss is "
                   f"{fliss_package.__version__}: program the board with this version's "
                   f"bitstream (make bitstream)\n")
    assert "gateware 0.0.9" in out


def test_port_errors(capsys, monkeypatch, tmp_path):
    status, out, err = fliss(capsys, "config", "--port", str(tmp_path / "ttyNONE"))
    assert (status, err) == (1, f"fliss: error: no serial port '{tmp_path / 'ttyNONE'}' "
                                f"(see `fliss ports`)\n")

    def denied(url, **kwargs):
        raise serial.SerialException(errno.EACCES, f"could not open port {url}: [Errno 13] "
                                                   f"Permission denied: {url!r}")
    monkeypatch.setattr(serial, "serial_for_url", denied)
    status, out, err = fliss(capsys, "config", "--port", "/dev/ttyUSB9")
    assert (status, err) == (1, "fliss: error: permission denied opening '/dev/ttyUSB9' (on "
                                "Linux, add yourself to the dialout group and log in again)\n")


def test_silent_board(capsys):
    master, slave = os.openpty()
    try:
        path = os.ttyname(slave)
        status, out, err = fliss(capsys, "config", "--port", path, "--timeout", "0.1",
                                 "--retries", "1")
    finally:
        os.close(master)
        os.close(slave)
    assert status == 1
    assert err == (f"fliss: error: the board on {path} does not answer (IDENTIFY: no reply in 2 "
                   f"attempts of 0.1 s); is it connected and powered, and is the baud rate "
                   f"right?\n")


def test_ports(capsys):
    status, out, err = fliss(capsys, "ports", "--all")
    assert status == 0 and out


# capture

def _prepare(model, **changes):
    with BoardClient(model.path, timeout_s=2.0) as board:
        board.write_registers(dict({"bin_shift": SHIFT}, **changes))
        return board.read_registers()


def test_capture_histograms_match_the_scene(model, capsys, tmp_path):
    settings = _prepare(model, delay_mode=2, mask_width=6, aggressor=1)
    seed = model.seed_for(model.starts)
    first_frame = model.next_frame
    output = tmp_path / "h.h5"
    status, out, err = fliss(capsys, "-q", "capture", "--port", model.path, "--integration",
                             "2ms", "--acquisitions", "6", "-o", str(output))
    assert status == 0, err
    capture = read_capture(output)
    assert capture.attrs["end_reason"] == "completed" and capture.attrs["complete"]
    assert capture.histograms.shape == (6, 8192 >> SHIFT)
    assert list(capture.frames) == list(range(first_frame, first_frame + 6))
    assert capture.complete.all() and (capture.shifts == SHIFT).all()
    assert np.all(np.diff(capture.times_s) >= 0)
    settings["integration"] = INTEGRATION
    assert capture.configuration == _recorded(settings)
    blocks = reference_blocks(settings, seed, 6)
    expected = np.array([histogram_of(events, SHIFT) for events in blocks])
    assert expected.sum() > 500
    np.testing.assert_array_equal(capture.histograms, expected)
    assert capture.identity["clock_hz"] == CLOCK_HZ
    assert capture.counters["link"]["dropped_frames"] == 0
    assert capture.counters["link"]["missing_packets"] == 0
    # The file names the package's version twice: the host's, and the gateware's identity.
    written = (Path(fliss_package.__file__).parent / "__init__.py").read_text()
    version = re.search(r'^__version__ = "([^"]+)"', written, flags=re.MULTILINE).group(1)
    assert capture.attrs["host_version"] == version
    assert capture.identity["gateware_version"] == version


def test_capture_raw_matches_the_scene(model, capsys, tmp_path):
    settings = _prepare(model, gate_start=200, gate_end=6000)
    seed = model.seed_for(model.starts)
    output = tmp_path / "r.h5"
    status, out, err = fliss(capsys, "capture", "--port", model.path, "--readout", "raw",
                             "--integration", "2ms", "--duration", "0.3s", "-o", str(output))
    assert status == 0, err
    assert out.startswith("saved ") and " events in " in out
    assert "[" in err and "events/s" in err          # the progress bar
    capture = read_capture(output)
    settings.update(integration=INTEGRATION, acquisition=1)
    assert capture.configuration == _recorded(settings)
    expected = np.concatenate(reference_blocks(settings, seed, 200))
    got = capture.events
    assert len(got) > 1000
    np.testing.assert_array_equal(got, expected[:len(got)])
    board_events = capture.counters["board_end"]["events"] - \
        capture.counters["board_start"]["events"]
    assert board_events == len(got)


def test_killed_board_leaves_what_was_received(capsys, tmp_path):
    chunks = 8192 >> SHIFT >> 7
    with model_board(scene=SCENE, kill_after=3 * chunks + 2) as model:
        settings = _prepare(model, full_readout=1)     # (chunks of 128 bins, counted above)
        seed = model.seed_for(model.starts)
        output = tmp_path / "k.h5"
        status, out, err = fliss(capsys, "-q", "capture", "--port", model.path,
                                 "--integration", "2ms", "--acquisitions", "50",
                                 "-o", str(output))
    assert status == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"fliss: error: lost the connection to the board on "
                               f"{model.path} (")
    assert lines[0].endswith(f"; saved what was received (4 histograms) to {output}")
    capture = read_capture(output)
    assert capture.attrs["end_reason"].startswith("board lost")
    assert not capture.attrs["complete"]
    assert list(capture.complete) == [True, True, True, False]
    settings["integration"] = INTEGRATION
    blocks = reference_blocks(settings, seed, 4)
    expected = np.array([histogram_of(events, SHIFT) for events in blocks])
    np.testing.assert_array_equal(capture.histograms[:3], expected[:3])
    np.testing.assert_array_equal(capture.histograms[3, :256], expected[3, :256])
    assert not capture.histograms[3, 256:].any()
    assert capture.counters["stream"]["incomplete_frames"] == 1


def test_hung_board_is_detected(capsys, tmp_path):
    with model_board(scene=SCENE, hang_after=20) as model:
        _prepare(model)
        output = tmp_path / "hang.h5"
        start = time.monotonic()
        status, out, err = fliss(capsys, "-q", "capture", "--port", model.path,
                                 "--timeout", "0.2", "--retries", "1", "--integration", "2ms",
                                 "--acquisitions", "50", "-o", str(output))
    assert status == 1
    assert time.monotonic() - start < 15
    assert err.startswith(f"fliss: error: the board on {model.path} does not answer "
                          f"(GET_STATUS: no reply in 2 attempts of 0.2 s)")
    assert read_capture(output).histograms.shape[0] >= 1


def test_corruption_is_detected_and_counted(capsys, tmp_path):
    with model_board(scene=SCENE, corrupt_every=7, corrupt_types={PacketType.HISTOGRAM}) \
            as model:
        settings = _prepare(model, full_readout=1)     # (full chunks: many to corrupt)
        seed = model.seed_for(model.starts)
        first_frame = model.next_frame
        output = tmp_path / "c.h5"
        status, out, err = fliss(capsys, "capture", "--port", model.path, "--integration",
                                 "2ms", "--acquisitions", "8", "-o", str(output))
        corrupted = len(model.corrupted)
    assert status == 0
    assert f"{corrupted} corrupt frames dropped, {corrupted} packets missing" in out
    assert err.strip().splitlines()[-1] == (
        f"fliss: warning: {corrupted} corrupt frames and {corrupted} missing packets on the "
        f"link (counted in the file)")
    capture = read_capture(output)
    assert capture.counters["link"]["dropped_frames"] == corrupted > 3
    assert capture.counters["link"]["missing_packets"] == corrupted
    settings["integration"] = INTEGRATION
    blocks = reference_blocks(settings, seed, 8)
    expected = np.array([histogram_of(events, SHIFT) for events in blocks])
    assert list(capture.frames) == list(range(first_frame, first_frame + 8))
    assert not capture.complete.all()
    for row, complete, truth in zip(capture.histograms, capture.complete, expected):
        if complete:
            np.testing.assert_array_equal(row, truth)
        else:
            assert np.all(row[row != truth] == 0)


def test_capture_user_errors(model, capsys, tmp_path):
    existing = tmp_path / "x.h5"
    existing.write_bytes(b"")
    status, out, err = fliss(capsys, "capture", "--port", model.path, "-o", str(existing))
    assert (status, err) == (1, f"fliss: error: {existing} exists (use --overwrite to replace "
                                f"it)\n")
    status, out, err = fliss(capsys, "capture", "--port", model.path, "--integration", "10",
                             "-o", str(tmp_path / "y.h5"))
    assert (status, err) == (1, "fliss: error: --integration 10: give a unit: 10ms, or "
                                "800cycles\n")
    status, out, err = fliss(capsys, "capture", "--port", model.path, "--acquisitions", "0",
                             "-o", str(tmp_path / "y.h5"))
    assert (status, err) == (1, "fliss: error: --acquisitions must be at least 1, not 0\n")


def test_ctrl_c_stops_the_board_and_saves(tmp_path):
    with model_board(scene=SCENE) as model:
        _prepare(model)
        output = tmp_path / "int.h5"
        process = subprocess.Popen(
            [sys.executable, "-c", "import sys; from fliss.host.cli import main; "
             "sys.exit(main(sys.argv[1:]))", "capture", "--port", model.path, "--timeout", "2",
             "--integration", "2ms", "--acquisitions", "100000", "-o", str(output)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and model.next_frame < 5:
            time.sleep(0.05)
        time.sleep(0.3)
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=15)
        assert not model.running
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == \
        "fliss: interrupted; acquisition stopped, capture saved"
    capture = read_capture(output)
    assert capture.attrs["end_reason"] == "interrupted: SIGINT"
    assert len(capture.histograms) >= 3
    assert capture.counters["board_end"]["running"] == 0


# analyze and plot

def test_analyze_and_plot(model, capsys, tmp_path):
    _prepare(model, delay_mode=0)
    output = tmp_path / "a.h5"
    status, out, err = fliss(capsys, "-q", "capture", "--port", model.path, "--readout", "raw",
                             "--integration", "10ms", "--duration", "0.5s", "-o", str(output))
    assert status == 0, err
    capture = read_capture(output)
    status, out, err = fliss(capsys, "analyze", str(output))
    assert status == 0, err
    rows = [line.split() for line in out.splitlines() if line.strip()[:1].isdigit()]
    assert rows, out
    tof_ns = float(rows[0][1])
    assert abs(tof_ns - time_of_flight(SCENE.distance_m) * 1e9) < 0.5
    assert 1.5 < float(rows[0][2]) < 2.8        # FWHM of a 2.1 ns pulse, 4-code bins
    counts = np.bincount(capture.events["timestamp"].astype(np.int64) >> SHIFT,
                         minlength=2048)
    assert f"{int(counts.sum())} counts" in out
    png = tmp_path / "a.png"
    status, out, err = fliss(capsys, "plot", str(output), "-o", str(png))
    assert status == 0 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    status, out, err = fliss(capsys, "analyze", str(tmp_path / "none.h5"))
    assert (status, err) == (1, f"fliss: error: no such file: {tmp_path / 'none.h5'}\n")
    (tmp_path / "bad.h5").write_bytes(b"not hdf5")
    status, out, err = fliss(capsys, "analyze", str(tmp_path / "bad.h5"))
    assert (status, err) == (1, f"fliss: error: '{tmp_path / 'bad.h5'}' is not an HDF5 file "
                                f"(file signature not found), not a capture file\n")
    with h5py.File(tmp_path / "other.h5", "w"):
        pass
    status, out, err = fliss(capsys, "plot", str(tmp_path / "other.h5"), "-o",
                             str(tmp_path / "b.png"))
    assert (status, err) == (1, f"fliss: error: '{tmp_path / 'other.h5'}' is not a FLISS "
                                f"capture file\n")


def test_events_dropped_on_the_board_are_reported(capsys, tmp_path):
    # A 115 200 baud line carries about 1 500 events per second: the rest is dropped at the
    # board's FIFO, counted there, and reported with the capture.
    with model_board(scene=SCENE, baud=115_200, line_limited=True) as model:
        output = tmp_path / "slow.h5"
        status, out, err = fliss(capsys, "capture", "--port", model.path, "--readout", "raw",
                                 "--integration", "10ms", "--duration", "0.3s",
                                 "-o", str(output))
        dropped = model.status["dropped_fifo"]
    assert status == 0, err
    capture = read_capture(output)
    start, end = capture.counters["board_start"], capture.counters["board_end"]
    accepted = end["events"] - start["events"]
    assert dropped > 1000 and end["dropped_fifo"] - start["dropped_fifo"] == dropped
    assert len(capture.events) + dropped == accepted
    assert f"{accepted} events accepted, {dropped} dropped on the board" in out
    assert err.strip().splitlines()[-1] == (
        f"fliss: warning: {dropped} events dropped on the board (counted in the file): the "
        f"link is too slow for this event rate; use a higher baud rate or histogram mode")


def _recorded(settings):
    """What a capture file keeps of the registers: all but the write-only key."""
    return {name: value for name, value in settings.items() if not BY_NAME[name].write_only}


def _histogram_file(path):
    # A histogram capture of 2 rows, bins of 4 codes (200 ps): a peak at bin 300 (60 ns).
    from fliss.host.fileformat import CaptureWriter
    from fliss.host.stream import HistogramFrame
    identity = {"protocol": PROTOCOL_VERSION, "gateware_version": "1.0", "registers": 1,
                "clock_hz": CLOCK_HZ, "baud": 12_000_000}
    writer = CaptureWriter(path, mode="histogram", identity=identity,
                           configuration=dict(defaults(CLOCK_HZ), bin_shift=SHIFT))
    for frame in range(2):
        counts = np.ones(8192 >> SHIFT, np.uint32)
        counts[300] = 50
        writer.add_histogram(HistogramFrame(frame, SHIFT, counts, True, 0, 1.0 + frame))
    writer.close("completed")


def test_plot_range_is_shown(capsys, tmp_path, monkeypatch):
    # --range 0ns 200ns, plot's own example, shows 0 to 200 ns.
    from matplotlib.figure import Figure
    _histogram_file(tmp_path / "h.h5")
    limits = []
    save = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda figure, *args, **kwargs: (
        limits.append(figure.axes[0].get_xlim()), save(figure, *args, **kwargs)))
    output = tmp_path / "h.png"
    status, out, err = fliss(capsys, "plot", str(tmp_path / "h.h5"), "--range", "0ns", "200ns",
                             "-o", str(output))
    assert (status, out, err) == (0, f"wrote {output}\n", "")
    assert limits == [pytest.approx((0.0, 200.0))]


def test_plot_writes_the_file_named(capsys, tmp_path):
    # -o without a suffix writes a PNG under the very name given (matplotlib would add .png).
    _histogram_file(tmp_path / "h.h5")
    output = tmp_path / "outfile"
    status, out, err = fliss(capsys, "plot", str(tmp_path / "h.h5"), "-o", str(output))
    assert (status, out, err) == (0, f"wrote {output}\n", "")
    assert output.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not (tmp_path / "outfile.png").exists()


@pytest.mark.parametrize("argv, message", [
    (["--range", "200ns", "0ns"], "--range 200ns 0ns: START (200 ns) must be before END (0 s)"),
    (["--range", "100ns", "100ns"],
     "--range 100ns 100ns: START (100 ns) must be before END (100 ns)"),
    (["--range", "0", "200ns"], "--range 0 200ns: give a unit: 10ms or 75ns"),
    (["--range", "-5ns", "200ns"], "--range -5ns 200ns: time must not be negative, not '-5ns'"),
])
def test_plot_range_refusals(capsys, tmp_path, argv, message):
    _histogram_file(tmp_path / "h.h5")
    status, out, err = fliss(capsys, "plot", str(tmp_path / "h.h5"), *argv,
                             "-o", str(tmp_path / "x.png"))
    assert (status, out, err) == (1, "", f"fliss: error: {message}\n")
    assert not (tmp_path / "x.png").exists()


def test_show_key_without_a_key_is_refused(model, capsys):
    # --show-key prints the key the command writes; alone it had printed nothing, silently.
    status, out, err = fliss(capsys, "config", "--port", model.path, "--show-key")
    assert (status, out) == (1, "")
    assert err == ("fliss: error: --show-key prints the key this command writes: give --key "
                   "with it (a key on the board is never read back)\n")
