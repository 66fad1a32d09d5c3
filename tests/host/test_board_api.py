"""The Python API (host/board.py: ``fliss.connect``, ``Board``) against the model board."""

import os
import warnings

import numpy as np
import pytest

import fliss
from fliss.hdl.registers import defaults
from fliss.host.acquisition import capture
from fliss.host.board import Board, Events, Histogram, Histograms
from fliss.host.errors import UserError
from fliss.host.client import BoardClient
from fliss.host.errors import BoardError, BoardLost, PathError, SettingsError
from fliss.host.fileformat import read_capture
from fliss.host.settings import RoundingWarning
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene

import test_host_cli as host_cli


CLOCK_HZ = 80_000_000
SCENE = host_cli.SCENE         # the scene of the reference blocks


def reference_blocks(settings, seed, blocks):
    """Events of each integration block straight from the scene simulator, gated (the command
    line's reference, tests/host/test_host_cli.py, with the same scene)."""
    return host_cli.reference_blocks(settings, seed, blocks, integration=settings["integration"])


@pytest.fixture
def model():
    with model_board(scene=SCENE) as board:
        yield board


@pytest.fixture
def board(model):
    with fliss.connect(model.path, timeout_s=2.0) as board:
        yield board


def test_importable_from_fliss():
    assert fliss.Board is Board and fliss.connect.__module__ == "fliss.host.board"
    assert fliss.SettingsError is SettingsError and fliss.BoardError is BoardError
    assert {"connect", "Board", "Histograms", "Events"} <= set(dir(fliss))


def test_configure_with_units(model, board, capsys):
    with pytest.warns(RoundingWarning) as caught:
        result = board.configure(mode="masked", mask_width=6, integration="10ms",
                                 aggressor_offset="80ns", prf="500kHz")
    notes = result.notes
    assert result.changes == {"delay_mode": 2, "mask_width": 6, "integration": 800_000,
                              "aggressor_offset": 6, "period": 160}
    # 80 ns is 6.4 cycles of 12.5 ns: 6 cycles, 75 ns; 500 kHz is 160 cycles exactly.
    assert notes == ["aggressor_offset='80ns' is 6.4 clock cycles of 12.5 ns: using 6 cycles, "
                     "75 ns"]
    assert [str(w.message) for w in caught] == notes
    assert model.model.settings == dict(defaults(CLOCK_HZ), delay_mode=2, mask_width=6,
                                        integration=800_000, aggressor_offset=6, period=160)
    settings = board.settings
    assert (settings["mode"], settings["mask_width"], settings["integration"],
            settings["aggressor_offset"], settings["prf"]) == ("masked", 6, "10 ms", "75 ns",
                                                               "500 kHz")
    # What it reads back, it takes back unchanged and without notes.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert board.configure(settings).notes == []
    assert model.model.settings["aggressor_offset"] == 6
    assert capsys.readouterr() == ("", "")


def test_refused_settings_write_nothing(model, board, capsys):
    for settings, message in (
            ({"integration": 10}, "integration=10: give a unit: 10ms, or 800cycles"),
            ({"prf": 1}, "prf=1: give a unit: 80MHz, 1kHz or 1e6Hz"),
            ({"prf": "1e6"}, "prf='1e6': give a unit: 80MHz, 1kHz or 1e6Hz"),
            ({"mask_width": 40}, "mask_width=40: takes values from 1 to 16 bits"),
            ({"mode": "masked", "pulse_width": "2us"},
             "pulse_width (2 µs, 160 cycles) must be shorter than prf (1 µs, 80 cycles)")):
        with pytest.raises(SettingsError) as info:
            board.configure(**settings)
        assert str(info.value) == message
        assert not isinstance(info.value, UserError)
    assert model.model.settings == defaults(CLOCK_HZ)
    assert model.model.refused == 0
    assert capsys.readouterr() == ("", "")


def test_acquire_matches_the_scene(model, board, capsys):
    board.configure(mode="masked", mask_width=6, aggressor="on", integration="2ms", bin_shift=2)
    settings = board.registers
    seed = model.seed_for(model.starts)
    result = board.acquire(4)
    assert isinstance(result, Histograms)
    assert result.counts.shape == (4, 2048) and result.time_s.shape == (2048,)
    # Bins of 4 codes of 50 ps: 200 ps wide, centres at 100 ps, 300 ps, ...
    np.testing.assert_allclose(result.time_s[:2], [100e-12, 300e-12])
    assert result.bin_s == pytest.approx(200e-12)
    assert result.complete.all() and result.lost == 0
    assert list(np.diff(result.frames)) == [1, 1, 1]
    expected = [np.bincount(events["timestamp"].astype(np.int64) >> 2, minlength=2048)
                for events in reference_blocks(settings, seed, 4)]
    assert np.sum(expected) > 500
    np.testing.assert_array_equal(result.counts, expected)
    assert result.settings["integration"] == "2 ms"
    assert not model.running                    # stopped afterwards
    assert capsys.readouterr() == ("", "")


def test_stream_yields_only_histograms(model, board):
    board.configure(integration="1ms")
    items = list(board.stream(5))
    assert len(items) == 5 and all(isinstance(item, Histogram) for item in items)
    assert [item.frame - items[0].frame for item in items] == [0, 1, 2, 3, 4]
    assert not model.running
    # An endless stream left early stops the board too.
    stream = board.stream()
    assert isinstance(next(stream), Histogram) and model.running
    stream.close()
    assert not model.running


def test_acquire_raw_matches_the_scene(model, board, capsys):
    board.configure(integration="2ms", gate_start="10ns", gate_end="300ns")
    settings = dict(board.registers, acquisition=1)
    seed = model.seed_for(model.starts)
    result = board.acquire_raw("200ms")
    assert isinstance(result, Events)
    assert result.events.dtype.names == ("timestamp", "address", "collision", "pulse")
    expected = np.concatenate(reference_blocks(settings, seed, 200))
    assert len(result) > 1000
    np.testing.assert_array_equal(result.events, expected[:len(result)])
    np.testing.assert_allclose(result.time_s, result.events["timestamp"] * 50e-12)
    assert result.time_s.min() >= 10e-9 and result.time_s.max() <= 300e-9
    # (the board's time: the model board may fall behind the wall clock)
    assert result.dropped == 0 and 0 < result.duration_s <= 0.25
    assert board.settings["readout"] == "raw"
    with pytest.raises(SettingsError, match=r"^duration=0.2: give a unit: 100ms, or 2s$"):
        board.acquire_raw(0.2)
    assert capsys.readouterr() == ("", "")


def test_timeouts_follow_the_integration_time(model, board):
    # The protocol client's stream() gave up after 2 s of silence; a 3 s histogram arrives
    # after 3 s: the wait is derived from the integration time.
    model.template = Scene(detections_per_pulse=0.001, background_hz=1e3)
    board.configure(integration="3s", bin_shift=4)
    assert board.wait_s() >= 6.0
    result = board.acquire(1)
    assert result.counts.shape == (1, 512) and result.complete.all()
    board.configure(integration="1ms")
    assert board.wait_s() < 3.0


def test_capture_needs_no_identify_and_uses_the_board_settings(model, tmp_path, capsys):
    with BoardClient(model.path, timeout_s=2.0) as client:
        client.write_registers({"integration": 80_000})        # 1 ms
        result = capture(client, str(tmp_path / "a.h5"), acquisitions=2,
                         integration_s=80_000 / CLOCK_HZ)
    assert result.complete and result.histograms == 2
    with fliss.connect(model.path, timeout_s=2.0) as board:
        board.configure(integration="5ms")
        result = board.capture(str(tmp_path / "b.h5"), acquisitions=2)
    assert result.complete
    saved = read_capture(tmp_path / "b.h5")
    assert saved.configuration["integration"] == 400_000
    assert saved.attrs["integration_s"] == pytest.approx(5e-3)
    assert capsys.readouterr() == ("", "")


def test_capture_keeps_an_existing_file(model, board, tmp_path):
    # As the command line refuses without --overwrite: the file is kept, the board not started.
    path = tmp_path / "kept.h5"
    path.write_bytes(b"precious")
    starts = model.starts
    with pytest.raises(PathError) as error:
        board.capture(str(path), acquisitions=1)
    assert str(error.value) == f"{path} exists (use overwrite=True to replace it)"
    assert path.read_bytes() == b"precious" and model.starts == starts
    board.configure(integration="1ms")
    result = board.capture(str(path), acquisitions=1, overwrite=True)
    assert result.complete and read_capture(path).histograms.shape[0] == 1


@pytest.mark.parametrize("mode", ["off", "masked"])
def test_acquire_raw_reports_the_board_time(model, board, mode):
    # duration_s is the board's time its events span, not the host's time around the call
    # (0.42 s for 100 ms): the clock cycles the model board simulated, which fires a pulse every
    # T (+ R in interval mode) of them, and falls behind the wall clock when busy.
    board.configure(mode=mode, mask_width=6, integration="2ms")
    result = board.acquire_raw("100ms")
    cycles = model._done_cycles                     # the board's time, simulated
    assert result.pulses == model.status["pulses"] > 5_000
    if mode == "off":
        assert result.duration_s == result.pulses * 80 / CLOCK_HZ      # 1 µs a pulse
    # (masked, Wm = 6: 80 + 31.5 cycles a pulse on average)
    assert result.duration_s == pytest.approx(cycles / CLOCK_HZ, rel=0.01)
    assert 0.005 < result.duration_s <= 0.12


def test_context_manager_closes_the_port(model):
    with fliss.connect(model.path, timeout_s=2.0) as board:
        assert board.client.serial.is_open
    assert not board.client.serial.is_open


def test_silent_port_is_said_at_its_first_timeout(caplog):
    master, slave = os.openpty()
    try:
        path = os.ttyname(slave)
        with pytest.raises(BoardLost, match="does not answer"):
            fliss.connect(path, timeout_s=0.1, retries=2)
    finally:
        os.close(master)
        os.close(slave)
    said = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert said == [f"the board on {path} is not answering yet (no reply to PING in 0.1 s); "
                    f"still trying"]


def test_connect_refuses_bad_arguments():
    with pytest.raises(SettingsError, match="^timeout_s must be positive, not 0$"):
        fliss.connect("loop://", timeout_s=0)


def test_smaller_build_refusal_names_the_setting():
    # A board whose build has no keyed source (the iCEBreaker's maxima): the refusal names the
    # setting as the caller wrote it, in the API and on the command line.
    maxima = {"delay_mode": 2, "key0": 0, "key1": 0, "key2": 0, "iv0": 0, "iv1": 0, "iv2": 0}
    with model_board(maxima=maxima) as model:
        with fliss.connect(model.path) as board:
            before = board.registers
            with pytest.raises(BoardError, match=r"^mode='keyed': the board's build does not "
                                                 r"take it \(a smaller build"):
                board.configure(mode="keyed")
            with pytest.raises(BoardError, match=r"^--iv 0x5: the board's build does not take "
                                                 r"it"):
                board.configure({"iv": "0x5"}, style="flag")
            assert board.registers == before           # nothing written
