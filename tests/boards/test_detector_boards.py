"""The detector's options on the boards without hardware: ``fliss board`` (both engines of
the virtual board) and the model board take ``--sensor-preset`` and one option per effect,
refuse a bad value in one line, and pass the detector to the scene that feeds the sensor: a
dark count rate set there is the rate of the events of a capture with no laser echo and no
ambient light, ``1 - exp(-r W)`` of the laser cycles (no dead time, one TDC window ``W``)."""

import math
import os

import pytest

from fliss.host.board import connect
from fliss.host.cli import main as fliss_main
from fliss.host.virtual import ENGINES, VirtualBoard
from fliss.sim.benches.runner import simulator_available
from fliss.sim.boards.model import model_board
from fliss.sim.boards.model_command import build_parser, main, scene_from_args
from fliss.sim.boards.options import detector_from_args
from fliss.sim.boards.virtual import scene_from_environment
from fliss.sim.scene import PRESETS, Detector

from conftest import require_fast_harness


WINDOW_S = 8192 * 50e-12                # a TDC window: 2**13 codes of 50 ps
DARK_HZ = 1e6
NO_LIGHT = ["--signal", "0", "--ambient", "0Hz", "--dark-count", "1MHz", "--dead-time", "0ns"]


@pytest.mark.parametrize("argv, message", [
    (["--afterpulsing", "140%"], "--afterpulsing 140%: a share is from 0 to 100 %"),
    (["--dark-count", "7"], "--dark-count 7: give a unit: 7kHz or 25Hz"),
    (["--dead-time=-22ns"], "--dead-time -22ns: must be a finite time, not negative"),
    (["--sensor-preset", "nikon"],
     "--sensor-preset nikon: unknown preset (known: paper, spcm20a, linospad2)"),
    (["--crosstalk", "3.5%"], "--crosstalk 3.5%: crosstalk needs neighbours: the pixel array "
                              "of --scene line, not the single pixel"),
    (["--afterpulse-tau", "40ns"], "--afterpulse-tau 40ns: does nothing without --afterpulsing"),
])
def test_a_bad_detector_option_is_refused_in_one_line_by_both_boards(capsys, argv, message):
    assert fliss_main(["board", *argv]) == 1
    assert capsys.readouterr().err == f"fliss: error: {message}\n"
    with pytest.raises(SystemExit) as exit:
        main(argv)
    assert exit.value.code == 2
    assert capsys.readouterr().err == f"python -m fliss.sim.boards.model: error: {message}\n"


def test_the_presets_are_listed_in_the_help(capsys):
    with pytest.raises(SystemExit):
        fliss_main(["board", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"{', '.join(PRESETS)} (default: the model's" in text
    for flag in ("--sensor-preset", "--afterpulsing", "--afterpulse-tau", "--crosstalk",
                 "--dark-count", "--jitter-tail", "--dead-time", "--paralysable", "--pdp",
                 "--hot-pixels"):
        assert flag in text


def test_the_options_describe_one_detector():
    args = build_parser().parse_args(["--sensor-preset", "spcm20a", "--afterpulsing", "1.4%",
                                      "--afterpulse-tau", "40ns", "--scene", "line",
                                      "--crosstalk", "3.5%", "--paralysable"])
    want = PRESETS["spcm20a"].replace(afterpulse_probability=0.014, afterpulse_s=(40e-9,),
                                      crosstalk_orthogonal=0.035, paralysable=True)
    assert detector_from_args(args) == want
    assert scene_from_args(args).detector == want
    # The virtual board hands it to its engines (the environment both read)
    board = VirtualBoard("verilator", engine="cocotb", detector=want, scene="line")
    old = dict(os.environ)
    try:
        os.environ.update(board.env)
        assert scene_from_environment().detector == want
        os.environ["FLISS_BOARD_DETECTOR"] = ""
        assert scene_from_environment().spad == Detector()
    finally:
        os.environ.clear()
        os.environ.update(old)


def _check_dark_rate(raw):
    """Events of a capture with dark counts only: one in ``1 - exp(-r W)`` of the cycles."""
    p = 1 - math.exp(-DARK_HZ * WINDOW_S)
    assert raw.dropped == 0
    n = raw.pulses
    assert n > 500
    assert abs(len(raw) - n * p) < 4.5 * math.sqrt(n * p * (1 - p)), (len(raw), n * p)


def test_the_model_board_sees_the_dark_counts_it_is_given():
    scene = scene_from_args(build_parser().parse_args(NO_LIGHT))
    with model_board(scene=scene, time_scale=0.05) as model, connect(model.path) as board:
        _check_dark_rate(board.acquire_raw("0.6s"))
    scene = scene_from_args(build_parser().parse_args(NO_LIGHT[:4]))
    with model_board(scene=scene, time_scale=0.05) as model, connect(model.path) as board:
        assert len(board.acquire_raw("0.3s")) == 0         # (without them: no light at all)


@pytest.mark.parametrize("engine", ENGINES)
def test_the_virtual_board_sees_the_dark_counts_it_is_given(engine):
    if engine == "fast":
        require_fast_harness()
    elif not simulator_available("verilator"):
        message = "simulator verilator is not installed"
        if os.environ.get("FLISS_REQUIRE_SIMULATORS"):
            pytest.fail(message + " (FLISS_REQUIRE_SIMULATORS is set)")
        pytest.skip(message)
    args = build_parser().parse_args(NO_LIGHT)
    with VirtualBoard("verilator", engine=engine, signal=0.0, ambient_hz=0.0, seed=3,
                      detector=detector_from_args(args)) as virtual, \
            connect(virtual.path) as board:
        # (at 250 kHz the UART carries every event: 1 MHz would fill the raw FIFO)
        board.configure(prf="250kHz")
        _check_dark_rate(board.acquire_raw("5s"))


def test_a_presets_crosstalk_on_the_single_pixel_is_noted():
    # (given as an option it is refused; a preset's is kept, and the boards say it does
    # nothing there)
    from fliss.sim.boards.options import detector_note
    single = build_parser().parse_args(["--sensor-preset", "linospad2"])
    assert detector_note(single, detector_from_args(single)) == (
        "the detector's crosstalk (0.22 % orthogonal, 0 % diagonal) needs neighbours: the "
        "single pixel has none (--scene line has)")
    line = build_parser().parse_args(["--sensor-preset", "linospad2", "--scene", "line"])
    assert detector_note(line, detector_from_args(line)) is None
