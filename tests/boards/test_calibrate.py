"""``fliss calibrate`` on the model board with a loopback (:mod:`fliss.sim.boards.loopback`): the
table against the modelled line's own tap delays, the self-test's check of it, too few hits,
refusals, and a calibration interrupted or killed."""

import numpy as np
import pytest

from fliss.analysis import calibration as analysis
from fliss.hdl.finetdc import UNIT_S
from fliss.hdl.finetdc.table import nominal_table
from fliss.host.board import connect
from fliss.host.calibration import calibrate, read_table
from fliss.host.errors import CalibrationError
from fliss.host.fileformat import read_capture
from fliss.host.selftest import selftest
from fliss.sim.boards.loopback import Loopback
from fliss.sim.boards.model import model_board
from fliss.sim.models.delay import delays

from loopback_runs import CLOCK_HZ, LINE, _InterruptAfter, _KillAfter, fliss, line_of


def test_calibration_needs_enough_hits_to_mean_something():
    # A calibration too short for its cover to mean anything fails, whatever it covered
    with model_board(loopback=Loopback(line=LINE)) as board, connect(board.path) as client:
        result = selftest(client, reference=delays,
                          durations_s={"calibration": 0.002, "calibration_frame": 0.002})
    detail = line_of(result, "calibration").detail
    assert line_of(result, "calibration").outcome == "fail"
    assert detail.endswith(": too few hits to check the cover (at least 25 a code)")
    hits = int(detail.split()[0])
    assert hits < 25 * 585


def test_calibrate_stores_the_table_and_captures_record_it(capsys, tmp_path):
    with model_board(loopback=Loopback(line=LINE)) as board:
        status, _, err = fliss(capsys, "calibrate", "--port", board.path, "--duration",
                               "500ms")
        assert status == 0, err
        table = np.array(board.model.table)
        path = tmp_path / "fine.h5"
        status, _, err = fliss(capsys, "capture", "--port", board.path, "--tdc", "fine",
                               "--readout", "raw", "--duration", "50ms", "-o", str(path), "-q")
        assert status == 0, err
        with connect(board.path) as client:
            assert np.array_equal(read_table(client.client), table)
    assert not np.array_equal(table, nominal_table())
    assert np.array_equal(read_capture(path).calibration_table, table)
    # Against the line's own taps: code c is the hit between thresholds c - 1 and c
    edges = LINE.thresholds_s
    true = (edges[:-1] + edges[1:]) / 2                 # centre of code 1, 2, ...
    codes = np.arange(2, 560)
    error = table[codes] * UNIT_S - true[codes - 1]
    error -= np.median(error)
    assert np.abs(error).max() < 20e-12


def test_calibration_table_from_the_histogram():
    # The library's table is the analysis's table of the codes it histogrammed
    with model_board(loopback=Loopback(line=LINE)) as board, connect(board.path) as client:
        result = calibrate(client, 0.2)
        assert np.array_equal(board.model.table, result.table)
    expected = analysis.table(result.counts, 1 / CLOCK_HZ, 12.5e-12, width=12)
    assert np.array_equal(result.table, expected)
    assert result.first_code == 1 and len(result.empty_codes) == 0


def test_calibrate_refuses_a_board_without_the_fine_tdc(capsys, up5k_maxima):
    with model_board(maxima=up5k_maxima) as board:
        status, out, err = fliss(capsys, "calibrate", "--port", board.path)
    assert (status, out) == (1, "")
    assert err == f"fliss: error: the board on {board.path} has no fine TDC (its build refuses " \
                  f"the fine TDC's registers; only the ULX3S's has one)\n"


def calibrate_command(capsys, board, *options):
    """``fliss calibrate`` on ``board`` with ``options``: its status and stderr, the board's
    table before and after, and its registers after."""
    with connect(board.path) as client:
        before = read_table(client.client)
    status, _, err = fliss(capsys, "calibrate", "--port", board.path, *options)
    with connect(board.path) as client:
        return status, err, before, read_table(client.client), client.registers


def test_calibrate_refuses_too_few_hits(capsys):
    # 5 µs of a 2.4 MHz oscillator: some 12 hits over 680 codes, not 25 a code
    with model_board(loopback=Loopback(line=LINE)) as board:
        status, err, before, after, _ = calibrate_command(capsys, board, "--duration", "5us")
        assert status == 1
        assert err.startswith("fliss: error: 1")
        assert " hits are too few for a table: it needs 25 a code on average, " in err
        assert err.endswith("the board's table is left as it was (force it to write this "
                            "one)\n")
        assert np.array_equal(before, after)
        # Forced, it writes it; the next self-test finds the table far from the oscillator's
        status, _, err = fliss(capsys, "calibrate", "--port", board.path, "--duration", "5us",
                               "--force")
        assert status == 0 and "(forced: too few hits)" in err
        status, out, _ = fliss(capsys, "selftest", "--port", board.path)
    assert status == 1
    calibration = next(line for line in out.splitlines() if line.startswith("calibration"))
    assert "the board's calibration table looks bad: code " in calibration
    assert calibration.endswith("(more than 1000 ps apart): run fliss calibrate again")


def test_an_interrupted_calibration_says_the_table_is_partial():
    def progress(stage):
        return _InterruptAfter(300 if stage == "table" else 10 ** 6)

    with model_board(loopback=Loopback(line=LINE)) as board, connect(board.path) as client:
        with pytest.raises(CalibrationError) as caught:
            calibrate(client, 0.3, progress=progress)
    assert str(caught.value) == (
        "interrupted while writing the calibration table: the board's table is partial (codes "
        "0 to 298 new, 299 to 1023 as they were); run fliss calibrate again, or configure the "
        "FPGA again for the nominal table")


@pytest.mark.parametrize("stop", [_InterruptAfter, _KillAfter], ids=["ctrl-c", "kill"])
def test_calibrate_stopped_before_the_table_leaves_it(capsys, monkeypatch, stop):
    # Ctrl-C, or a kill (SIGTERM) the command turns into the same stop
    import fliss.host.commands.calibrate as command
    monkeypatch.setattr(command, "Progress", lambda *args, **kwargs: stop(2))
    with model_board(loopback=Loopback(line=LINE)) as board:
        status, err, before, after, settings = calibrate_command(capsys, board, "--duration",
                                                                 "0.3s")
    assert status == 130
    assert err.splitlines()[-1] == "fliss calibrate: interrupted before the table was written: " \
                                   "the board's table is left as it was"
    assert np.array_equal(before, after)
    assert settings["tdc_input"] == 0 and settings["tdc_source"] != 3     # put back


def test_a_calibration_pass_says_how_much_of_the_table_it_read():
    # The check reads TABLE_SAMPLES entries back, not the whole table: an entry it does not read
    # (here a wrong one between two it reads) passes, and the line must say a sample agreed,
    # not that "the board's table agrees".
    loopback = Loopback(jumper=None, line=LINE)
    with model_board(loopback=loopback) as board, connect(board.path) as client:
        calibrate(client, 0.3)
        raw = client.client
        raw.write_registers({"table_address": 100, "table_data": 4000},
                            current=raw.read_registers())
        assert read_table(raw, codes=[100])[0] == 4000
        result = selftest(client, reference=delays)
    check = line_of(result, "calibration")
    codes = result.calibration.last_code - result.calibration.first_code + 1
    assert check.outcome == "pass"
    assert check.detail.endswith(f"; the board's table agrees at the 32 of its {codes} entries "
                                 f"read back")
