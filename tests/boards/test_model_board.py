"""The Python model board's STATUS against the gateware's rules."""

import argparse
import time

import numpy as np
import pytest

from fliss.host.client import BoardClient
from fliss.host.stream import EventBatch
from fliss.sim.models.command import CommandModel
from fliss.host.cli import main as fliss_main
from fliss.sim.boards.model import model_board, scene_for
from fliss.sim.boards.model_command import build_parser, main
from fliss.sim.scene import Scene, line_pixels


def test_pulse_count_restarts_with_each_start():
    # The gateware's scheduler restarts its pulse index on every START (hdl/delay/scheduler.py), so
    # STATUS `pulses` counts the pulses of the running acquisition only.
    with model_board() as model, BoardClient(model.path, timeout_s=2.0) as board:
        board.start()
        time.sleep(0.3)
        first = board.status()["pulses"]
        board.stop()
        board.start()
        again = board.status()["pulses"]
        board.stop()
    assert first > 0
    assert again < first


def test_line_scene_events_carry_the_pixels():
    # The model board with the line scene: raw events from the column of 60 pixels, each
    # pixel's echo at its own time of flight (object 2.5 m before pixels 20-39, wall 4 m).
    pixels = line_pixels(sensor="per_pixel")
    scene = Scene(detections_per_pulse=0.05, background_hz=1e4, pixels=pixels)
    with model_board(scene=scene, time_scale=0.05) as model, \
            BoardClient(model.path, timeout_s=2.0) as board:
        board.write_registers({"acquisition": 1, "integration": 80_000})
        board.start()
        time.sleep(0.6)
        board.stop()
        time.sleep(0.2)
        data = board.take_data()
    events = np.concatenate([item.events for item in data if isinstance(item, EventBatch)])
    assert len(events) > 500 and not events["collision"].any()
    addresses = events["address"].astype(int)
    assert set(addresses) <= set(range(60)) and len(set(addresses)) > 50
    for low, high, distance_m in ((0, 20, 4.0), (20, 40, 2.5), (40, 60, 4.0)):
        chosen = (addresses >= low) & (addresses < high)
        tof_codes = 2 * distance_m / 299_792_458.0 / 50e-12
        assert abs(np.median(events["timestamp"][chosen]) - tof_codes) < 15


def test_scene_for_keeps_the_pixel_array():
    pixels = line_pixels()
    settings = dict(CommandModel(80_000_000, 12_000_000).settings, aggressor=1)
    scene = scene_for(settings, Scene(pixels=pixels))
    assert scene.pixels is pixels and len(scene.aggressors) == 1
    assert scene_for(settings).pixels is None


def test_command_line_refuses_a_bad_scene(capsys):
    with pytest.raises(SystemExit) as exit:
        main(["--scene", "line", "--object-m", "0"])
    assert exit.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        "python -m fliss.sim.boards.model: error: Object distance (m) must be a finite positive "
        "number, not 0.0")


def _options(parser):
    return {option for action in parser._actions for option in action.option_strings}


def test_the_model_board_takes_the_options_of_fliss_board(capsys):
    # One name per setting: every option of the model board is fliss board's, which has only
    # the simulator's and the engine's own besides (the builds' and the jumper's the model
    # takes too).
    from fliss.host.commands import board as board_command
    commands = argparse.ArgumentParser().add_subparsers()
    board_command.register(commands, argparse.HelpFormatter)
    model, board = _options(build_parser()), _options(commands.choices["board"])
    assert model - board == set()
    assert board - model == {"--sim", "--engine"}
    # A rate takes its unit in both.
    message = "--ambient 1e5: give a rate with its unit, not negative: 100kHz, 1e5Hz or 0Hz"
    with pytest.raises(SystemExit):
        main(["--ambient", "1e5"])
    assert capsys.readouterr().err.splitlines()[-1] == \
        f"python -m fliss.sim.boards.model: error: {message}"
    assert fliss_main(["board", "--ambient", "1e5"]) == 1
    assert capsys.readouterr().err == f"fliss: error: {message}\n"


def test_the_model_board_models_the_builds_and_the_jumper(capsys):
    # --fine-tdc: a build with the fine TDC (its table's pointer moves); without, none; --small,
    # no aggressor emitter; --jumper, its loopback; --baud, the identity's rate
    from fliss.host.board import connect
    from fliss.host.calibration import has_fine_tdc
    from fliss.host.errors import BoardRefused
    from fliss.sim.boards.model_command import _build_from_args
    parser = build_parser()
    for argv, fine, aggressor in ((["--fine-tdc", "--jumper", "aggressor"], True, True),
                                  ([], False, True), (["--small"], False, False)):
        build = _build_from_args(parser.parse_args([*argv, "--baud", "3M"]))
        with model_board(**build) as board, connect(board.path) as client:
            assert has_fine_tdc(client.client) == fine
            assert client.identity.baud == 3_000_000
            try:
                client.client.write_registers({"aggressor": 1})
                took = True
            except BoardRefused:
                took = False
            assert took == aggressor
        assert build["loopback"].jumper == ("aggressor" if "--jumper" in argv else None)
    with pytest.raises(SystemExit) as exit:
        main(["--small", "--fine-tdc"])
    assert exit.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == (
        "python -m fliss.sim.boards.model: error: the iCEBreaker's build has no fine TDC: "
        "--small or --fine-tdc, not both")


def test_a_crash_of_the_model_is_a_lost_board_not_a_silent_one(monkeypatch, caplog):
    # A bug in the model (or a library under it too old) stops its thread: the pty closes, so
    # the host is told at once that the board is gone, and the error is logged, not lost.
    from fliss.host.client import BoardClient
    from fliss.host.errors import BoardLost
    from fliss.sim.boards.model import ModelBoard

    def broken(self, item):
        raise RuntimeError("a bug in the model")

    monkeypatch.setattr(ModelBoard, "_receive", broken)
    started = time.monotonic()
    with model_board() as model:
        with pytest.raises(BoardLost, match="lost the connection to the board"):
            with BoardClient(model.path, timeout_s=2.0) as board:
                board.identify()
        assert repr(model.failed) == "RuntimeError('a bug in the model')"
    assert time.monotonic() - started < 4      # not the retries of a silent board
    assert "the model board stopped" in caplog.text and "a bug in the model" in caplog.text
