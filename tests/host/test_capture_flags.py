"""``fliss capture`` refuses a flag that does not apply to the readout it would capture (the
board's, or the one given with --readout), before it changes anything on the board, rather
than capture something else than asked (issue 41: `--acquisitions 6` on a board left in raw
readout made a 1 s raw capture)."""

import pytest

from fliss.hdl.registers import AcquisitionMode
from fliss.host.cli import main, parse_args
from fliss.host.client import BoardClient
from fliss.sim.boards.model import model_board


@pytest.fixture
def model():
    with model_board() as board:
        yield board


def fliss(capsys, *argv):
    status = main([str(arg) for arg in argv] + ["--timeout", "2"])
    out, err = capsys.readouterr()
    return status, out, err


def registers(model):
    with BoardClient(model.path, timeout_s=2.0) as board:
        return board.read_registers()


def set_readout(model, readout):
    with BoardClient(model.path, timeout_s=2.0) as board:
        board.write_registers({"acquisition": AcquisitionMode[readout.upper()].value})


def test_given_holds_the_options_typed_and_not_the_defaults(monkeypatch):
    monkeypatch.setenv("FLISS_PORT", "/dev/null")
    args = parse_args(["-q", "capture", "-o", "x.h5", "--duration", "2s"])
    assert args.given == {"quiet", "output", "duration"}
    assert args.port == "/dev/null" and args.acquisitions == 10     # defaults still there
    assert parse_args(["view", "x.h5", "--port", "p"]).given == {"file", "port"}


BOARD_RAW = ("the board's readout is raw (set by an earlier `fliss config` or capture)")
BOARD_HISTOGRAM = ("the board's readout is histogram (its reset value, or as an earlier "
                   "command left it)")


@pytest.mark.parametrize("board, argv, message", [
    ("raw", ["--acquisitions", "6"],
     f"--acquisitions applies to the histogram, image and depth readouts, not raw, and "
     f"{BOARD_RAW}: give --readout histogram (or image, depth), or --duration TIME for raw "
     f"events"),
    ("histogram", ["--readout", "raw", "--acquisitions", "6"],
     "--acquisitions applies to the histogram, image and depth readouts, not raw, and "
     "--readout raw is given here: give --readout histogram (or image, depth), or --duration "
     "TIME for raw events"),
    ("histogram", ["--duration", "6s"],
     f"--duration applies to the raw readout only, and {BOARD_HISTOGRAM}: give "
     f"--acquisitions N for histogram frames, or --readout raw"),
    ("depth", ["--duration", "1s"],
     "--duration applies to the raw readout only, and the board's readout is depth (set by an "
     "earlier `fliss config` or capture): give --acquisitions N for depth frames, or "
     "--readout raw"),
    ("raw", ["--readout", "image", "--duration", "1s"],
     "--duration applies to the raw readout only, and --readout image is given here: give "
     "--acquisitions N for image frames, or --readout raw"),
])
def test_a_flag_of_another_readout_is_refused_and_the_board_left_alone(
        model, capsys, tmp_path, board, argv, message):
    set_readout(model, board)
    before = registers(model)
    output = tmp_path / "c.h5"
    status, out, err = fliss(capsys, "capture", "--port", model.path, "--integration", "3ms",
                             "-o", output, *argv)
    assert (status, out, err) == (1, "", f"fliss: error: {message}\n")
    assert registers(model) == before       # not even --integration was written
    assert not output.exists() and not model.running


def test_the_flag_of_the_readout_in_force_is_taken(model, capsys, tmp_path):
    set_readout(model, "raw")
    status, out, err = fliss(capsys, "-q", "capture", "--port", model.path, "--duration",
                             "0.2s", "-o", tmp_path / "r.h5")
    assert status == 0, err
    status, out, err = fliss(capsys, "capture", "--port", model.path, "--readout", "histogram",
                             "--integration", "1ms", "--acquisitions", "3", "-o",
                             tmp_path / "h.h5")
    assert status == 0, err
    assert out.startswith(f"saved 3 histograms to {tmp_path / 'h.h5'}\n")


@pytest.mark.parametrize("argv, flags", [
    (["--shape", "2x4"], "--shape: an option"),
    (["--view-port", "0", "--victim-tof", "26ns"], "--view-port, --victim-tof: options"),
])
def test_options_of_the_view_without_view_are_refused(model, capsys, tmp_path, argv, flags):
    status, out, err = fliss(capsys, "capture", "--port", model.path, "-o", tmp_path / "c.h5",
                             *argv)
    assert (status, err) == (1, f"fliss: error: {flags} of the live view, which this capture "
                                f"does not show: add --view\n")


def test_a_view_option_that_does_not_fit_is_refused_before_the_board_changes(model, capsys,
                                                                            tmp_path):
    pytest.importorskip("bokeh")
    set_readout(model, "histogram")
    before = registers(model)
    status, out, err = fliss(capsys, "capture", "--port", model.path, "--readout", "raw",
                             "--duration", "0.2s", "-o", tmp_path / "c.h5", "--view",
                             "--view-port", "0", "--pixels", "4", "--shape", "3x3")
    assert (status, err) == (1, "fliss: error: --shape 3x3: 3 x 3 is not the capture's 4 "
                                "pixels\n")
    assert registers(model) == before       # neither --readout nor --pixels written
