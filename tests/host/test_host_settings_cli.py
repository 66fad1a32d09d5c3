"""Settings on the command line (issue 18): one meaning for each flag in `fliss config` and
`fliss capture`, capture at the board's settings, rounding said, global options anywhere."""

import os
import subprocess
import sys

import pytest

from fliss.hdl.registers import BY_NAME, defaults
from fliss.host.cli import main, parse_args
from fliss.host.fileformat import read_capture
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene


CLOCK_HZ = 80_000_000
SCENE = Scene(detections_per_pulse=0.1, background_hz=2e5)


def fliss(capsys, *argv):
    argv = list(argv)
    if "--port" in argv:
        argv += ["--timeout", "2"]
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture
def model():
    with model_board(scene=SCENE) as board:
        yield board


def test_capture_keeps_the_integration_config_set(model, capsys, tmp_path):
    status, out, err = fliss(capsys, "config", "--port", model.path, "--integration", "5ms",
                             "--bin-shift", "3")
    assert (status, err) == (0, "")
    status, out, err = fliss(capsys, "-q", "capture", "--port", model.path,
                             "--acquisitions", "2", "-o", str(tmp_path / "a.h5"))
    assert (status, err) == (0, "")
    saved = read_capture(tmp_path / "a.h5")
    # 5 ms = 400 000 cycles of 12.5 ns, recorded as used
    assert saved.configuration["integration"] == 400_000
    assert saved.configuration["bin_shift"] == 3
    assert saved.attrs["integration_s"] == pytest.approx(5e-3)
    assert saved.histograms.shape == (2, 1024)


def test_capture_flags_change_the_board_first(model, capsys, tmp_path):
    status, out, err = fliss(capsys, "capture", "-q", "--port", model.path, "--integration",
                             "2ms", "--mode", "masked", "--mask-width", "5",
                             "--acquisitions", "2", "-o", str(tmp_path / "b.h5"))
    assert (status, out, err) == (0, "", "")
    saved = read_capture(tmp_path / "b.h5")
    expected = dict(defaults(CLOCK_HZ), integration=160_000, delay_mode=2, mask_width=5)
    assert saved.configuration == {name: value for name, value in expected.items()
                                   if not BY_NAME[name].write_only}     # never the key
    assert model.model.settings == expected      # and left so, as `fliss config` would


def test_readout_set_by_config_is_captured(model, capsys, tmp_path):
    assert fliss(capsys, "config", "--port", model.path, "--readout", "raw",
                 "--integration", "2ms")[0] == 0
    status, out, err = fliss(capsys, "-q", "capture", "--port", model.path, "--duration",
                             "0.2s", "-o", str(tmp_path / "r.h5"))
    assert status == 0, err
    saved = read_capture(tmp_path / "r.h5")
    assert saved.attrs["mode"] == "raw" and len(saved.events) > 100


def test_mode_is_the_delay_source_in_capture_too(capsys):
    with pytest.raises(SystemExit):
        parse_args(["capture", "--port", "x", "--mode", "raw", "-o", "x.h5"])
    assert "argument --mode: invalid choice: 'raw' (choose from 'off', 'mseq', 'masked', 'keyed')" in \
        capsys.readouterr().err


def test_rounding_is_said_in_one_line(model, capsys):
    status, out, err = fliss(capsys, "config", "--port", model.path, "--aggressor-offset",
                             "80ns", "--prf", "3MHz", "--pulse-width", "20ns")
    assert status == 0
    # 80 ns = 6.4 cycles of 12.5 ns -> 6 = 75 ns; 80 MHz / 3 MHz = 26.67 -> 27 = 2.963 MHz;
    # 20 ns = 1.6 cycles -> 2 = 25 ns
    assert err.splitlines() == [
        "fliss: warning: --prf 3MHz is a period of 26.67 clock cycles: using 27 cycles, "
        "2.963 MHz",
        "fliss: warning: --pulse-width 20ns is 1.6 clock cycles of 12.5 ns: using 2 cycles, "
        "25 ns",
        "fliss: warning: --aggressor-offset 80ns is 6.4 clock cycles of 12.5 ns: using 6 "
        "cycles, 75 ns"]
    assert (model.model.settings["aggressor_offset"], model.model.settings["period"],
            model.model.settings["pulse_width"]) == (6, 27, 2)
    lines = {line.split()[0]: line for line in out.splitlines()[2:]}
    assert lines["aggressor_offset"].split()[:3] == ["aggressor_offset", "*", "6"]   # set


@pytest.mark.parametrize("duration, message", [
    ("1", "--duration 1: give a unit: 100ms, or 2s"),
    ("soon", "--duration soon: cannot read 'soon' as a time (for example 10ms or 75ns)"),
])
def test_capture_duration_takes_a_unit(model, capsys, tmp_path, duration, message):
    status, out, err = fliss(capsys, "capture", "--port", model.path, "--duration", duration,
                             "-o", str(tmp_path / "d.h5"))
    assert (status, err) == (1, f"fliss: error: {message}\n")
    assert not (tmp_path / "d.h5").exists()


def test_grid_and_interval_are_short_for_scheduler(model, capsys):
    assert fliss(capsys, "config", "--port", model.path, "--grid")[0] == 0
    assert model.model.settings["grid"] == 1
    assert fliss(capsys, "config", "--port", model.path, "--scheduler", "interval")[0] == 0
    assert model.model.settings["grid"] == 0


@pytest.mark.parametrize("argv, verbose, quiet", [
    (["-q", "capture", "-o", "x.h5"], 0, 1),
    (["capture", "-q", "-o", "x.h5"], 0, 1),
    (["-q", "capture", "-q", "-o", "x.h5"], 0, 2),
    (["config", "-v", "-v"], 2, 0),
    (["-v", "config", "--verbose"], 2, 0),
    (["prf-table", "-q"], 0, 1),
])
def test_global_options_after_the_sub_command(argv, verbose, quiet, monkeypatch):
    monkeypatch.setenv("FLISS_PORT", "loop://")
    args = parse_args(argv)
    assert (args.verbose, args.quiet) == (verbose, quiet)


def test_silent_board_is_said_at_once(tmp_path):
    master, slave = os.openpty()
    try:
        path = os.ttyname(slave)
        run = subprocess.run([sys.executable, "-m", "fliss", "config", "--port", path,
                              "--timeout", "0.2", "--retries", "1"], capture_output=True,
                             text=True, timeout=60)
    finally:
        os.close(master)
        os.close(slave)
    assert run.returncode == 1
    assert run.stderr.splitlines() == [
        f"fliss: warning: the board on {path} is not answering yet (no reply to PING in "
        f"0.2 s); still trying",
        f"fliss: error: the board on {path} does not answer (IDENTIFY: no reply in 2 attempts "
        f"of 0.2 s); is it connected and powered, and is the baud rate right?"]
