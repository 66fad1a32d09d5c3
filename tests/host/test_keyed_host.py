"""Host side of the keyed source: ``fliss config --key/--iv`` against the model board, and
``fliss sequence --mode keyed`` against the published Trivium vector."""

import pytest

import fliss as fliss_api
from fliss.hdl.registers import defaults, value_of
from fliss.host.client import BoardClient
from fliss.host.errors import SettingsError
from fliss.sim.boards.model import model_board
from test_host_cli import fliss


#: eSTREAM set 1 vector 0 (key 80 00 … 00, IV 0): keystream bytes 38 EB 86 FF, least
#: significant bit first: 4-bit delays 8, 3, 11, 14, 6, 8, 15, 15.
VECTOR_NIBBLES = [0x8, 0x3, 0xB, 0xE, 0x6, 0x8, 0xF, 0xF]

#: A key of 20 hex digits.
KEY = "0123456789abcdef0123"


@pytest.fixture
def model():
    with model_board() as board:
        yield board


def test_sequence_keyed_published_vector(capsys):
    status, out, err = fliss(capsys, "sequence", "--mode", "keyed", "--key",
                             "80 00 00 00 00 00 00 00 00 00", "--iv", "0", "--mask-width", "4",
                             "--count", "8")
    assert status == 0, err
    assert [int(line) for line in out.split()] == VECTOR_NIBBLES


@pytest.mark.parametrize("argv, message", [
    (["--key", "12345678901234567890a", "--iv", "0"],
     "A Trivium key is 20 hex digits (80 bits, as the test vectors print it), not "
     "'12345678901234567890a' (21 digits)"),
    # A short key is not padded with zeros: 12345 is not 00000000000000012345.
    (["--key", "12345", "--iv", "0"],
     "A Trivium key is 20 hex digits (80 bits, as the test vectors print it), not '12345' "
     "(5 digits)"),
    (["--key", KEY, "--iv", "0xg"],
     "A Trivium IV is up to 20 hex digits (80 bits, as the test vectors print it), not '0xg'"),
    (["--iv", "0"], "--mode keyed needs --key and --iv"),
    (["--key", KEY, "--iv", "0", "--mask-width", "17"],
     "Mask width must be an integer from 1 to 16, not 17"),
])
def test_sequence_keyed_refusals(capsys, argv, message):
    status, out, err = fliss(capsys, "sequence", "--mode", "keyed", *argv)
    assert (status, out, err) == (1, "", f"fliss: error: {message}\n")


def test_config_random_key_is_not_shown_and_reads_zero(model, capsys):
    status, out, err = fliss(capsys, "config", "--port", model.path, "--mode", "keyed",
                             "--mask-width", "5", "--key", "random", "--iv", "0x10")
    assert status == 0, err
    key = value_of(model.model.settings, "key")
    assert key != 0
    for text in (f"{key:x}", f"{key & 0xFFFFFFFF}", f"{key & 0xFFFFFFFF:x}"):
        assert text not in out + err
    with BoardClient(model.path, timeout_s=2.0) as board:
        values = board.read_registers()
    assert [values[f"key{k}"] for k in range(3)] == [0, 0, 0]
    assert value_of(values, "iv") == 0x10        # the IV in use (stopped: the next run's)
    # Asked for, the key is printed
    status, out, err = fliss(capsys, "config", "--port", model.path, "--key",
                             "0x0123456789abcdef0123", "--show-key")
    assert status == 0, err
    assert out.splitlines()[0] == "key 0x0123456789abcdef0123"


def test_config_iv_must_go_up(model, capsys):
    status, out, err = fliss(capsys, "config", "--port", model.path, "--mode", "keyed",
                             "--key", KEY, "--iv", "0x20")
    assert status == 0, err
    # The IV in use again: nothing to write (the settings read back go back unchanged)
    status, out, err = fliss(capsys, "config", "--port", model.path, "--iv", "0x20")
    assert status == 0, err
    status, out, err = fliss(capsys, "config", "--port", model.path, "--iv", "0x1f")
    assert status == 1
    assert err == ("fliss: error: --iv: the IV (0x0000000000000000001f) must be above the IV "
                   "in use (0x00000000000000000020) unless a new key is written with it: under "
                   "one key no IV is used twice (give a higher IV or a new key)\n")
    status, out, err = fliss(capsys, "config", "--port", model.path, "--iv", "0x21")
    assert status == 0, err
    status, out, err = fliss(capsys, "config", "--port", model.path, "--key", "zz")
    assert (status, err) == (1, "fliss: error: --key zz: A Trivium key is 20 hex digits "
                                "(80 bits, as the test vectors print it) or random, not 'zz'\n")


@pytest.mark.parametrize("key", ["12345", "0x12345", "0123456789abcdef012", "1" * 21])
def test_a_key_is_all_20_digits(model, capsys, key):
    # 12345 would be read as the key 00000000000000012345, one nobody meant: refused, here and
    # in the Python API, and nothing is written.
    digits = len(key.removeprefix("0x"))
    expected = (f"A Trivium key is 20 hex digits (80 bits, as the test vectors print it) or "
                f"random, not '{key}' ({digits} digits)")
    status, out, err = fliss(capsys, "config", "--port", model.path, "--mode", "keyed",
                             "--key", key, "--iv", "0x20")
    assert (status, err) == (1, f"fliss: error: --key {key}: {expected}\n")
    with fliss_api.connect(model.path, timeout_s=2.0) as board:
        with pytest.raises(SettingsError) as error:
            board.configure(key=key)
    assert str(error.value) == f"key={key!r}: {expected}"
    assert value_of(model.model.settings, "key") == 0
    assert model.model.settings == defaults(80_000_000)
    # All 20 digits, spaced as the test vectors print them, or with 0x, are taken.
    status, out, err = fliss(capsys, "config", "--port", model.path, "--key",
                             "80 00 00 00 00 00 00 00 00 00", "--show-key")
    assert status == 0, err
    assert out.splitlines()[0] == "key 0x80000000000000000000"


def test_capture_keyed_on_the_model_board(tmp_path, capsys):
    # A capture in keyed mode on the model board: the file records the IV in use, never the
    # key, and the scene simulator fires the laser with the keyed delays of that IV.
    from fliss.host.fileformat import read_capture
    from fliss.sim.models import delay as model
    from fliss.sim.scene import Scene
    with model_board(scene=Scene(detections_per_pulse=0.1, background_hz=2e5)) as board:
        status, out, err = fliss(capsys, "config", "--port", board.path, "--mode", "keyed",
                                 "--mask-width", "4", "--key", "0x0123456789abcdef0123",
                                 "--iv", "0x40")
        assert status == 0, err
        path = tmp_path / "keyed.h5"
        status, out, err = fliss(capsys, "capture", "--port", board.path, "-o", str(path),
                                 "--acquisitions", "2", "--integration", "1ms")
        assert status == 0, err
        schedule = board.simulation.scene.victim
    capture = read_capture(path)
    configuration = capture.configuration if hasattr(capture, "configuration") else \
        capture["configuration"]
    assert value_of(configuration, "iv") == 0x40
    assert not {f"key{k}" for k in range(3)} & set(configuration)     # never the key
    assert (schedule.mode, schedule.key, schedule.iv) == \
        (model.DelayMode.KEYED, 0x0123456789ABCDEF0123, 0x40)


def test_a_keyed_capture_is_labelled_keyed(tmp_path, capsys, monkeypatch):
    # `fliss plot` names each curve by its capture's delay mode, from the table of modes
    from matplotlib.figure import Figure
    from fliss.host.commands.plot import curve_label
    from fliss.host.fileformat import read_capture
    with model_board() as board:
        status, out, err = fliss(capsys, "config", "--port", board.path, "--mode", "keyed",
                                 "--mask-width", "5", "--key", "0" * 19 + "1", "--iv", "0x10")
        assert status == 0, err
        path = tmp_path / "keyed.h5"
        status, out, err = fliss(capsys, "-q", "capture", "--port", board.path, "-o",
                                 str(path), "--acquisitions", "2", "--integration", "1ms")
        assert status == 0, err
    configuration = read_capture(path).configuration
    assert configuration["delay_mode"] == 3 and configuration["mask_width"] == 5
    assert curve_label(str(path), configuration) == "keyed.h5 (FLISS keyed Wm=5, aggressor off)"
    legends = []
    save = Figure.savefig

    def savefig(figure, *args, **kwargs):
        legends.append([text.get_text() for legend in figure.legends for text in legend.get_texts()])
        return save(figure, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    status, out, err = fliss(capsys, "-q", "plot", str(path), "-o", str(tmp_path / "k.png"))
    assert status == 0, err
    assert legends == [["keyed.h5 (FLISS keyed Wm=5, aggressor off)"]]


LAST_IV = (1 << 80) - 1


def test_the_last_iv_runs_once_then_a_new_key(tmp_path, capsys):
    # The IV 2**80 - 1 (above the IV in use, so taken) runs one capture; after it the board's
    # keyed source has used every IV under its key (STATUS ivs_used_up): it never goes on with
    # IV 0. The next capture in keyed mode is refused before its START, with one line and no
    # file, and so are a higher IV (there is none) and keyed mode chosen again without a key;
    # a new key runs again.
    from fliss.host.errors import IvsUsedUp
    with model_board() as board:
        status, out, err = fliss(capsys, "config", "--port", board.path, "--mode", "keyed",
                                 "--mask-width", "4", "--key", KEY, "--iv", "0x10")
        assert status == 0, err
        status, out, err = fliss(capsys, "config", "--port", board.path,
                                 "--iv", f"{LAST_IV:#x}")
        assert status == 0, err
        first = tmp_path / "first.h5"
        status, out, err = fliss(capsys, "capture", "--port", board.path, "-o", str(first),
                                 "--acquisitions", "1", "--integration", "1ms")
        assert (status, err.splitlines()[-1]) == (
            0, "fliss: warning: the keyed source has used every IV under its key (this run used "
               "the last): a run in keyed mode fires no laser pulse until a new key is written "
               "(fliss config --key HEX, or --key random)")
        with BoardClient(board.path, timeout_s=2.0) as client:
            assert client.status()["ivs_used_up"] == 1
            assert value_of(client.read_registers(), "iv") == LAST_IV
        second = tmp_path / "second.h5"
        status, out, err = fliss(capsys, "capture", "--port", board.path, "-o", str(second),
                                 "--acquisitions", "1", "--integration", "1ms")
        used_up = (f"the keyed source has used every IV under its key (the IV in use, "
                   f"{LAST_IV:#022x}, is the last): in keyed mode the board would fire no "
                   f"laser pulse; write a new key (fliss config --key HEX, or --key random)")
        assert (status, err) == (1, f"fliss: error: {used_up}\n")
        assert not second.exists()
        assert board.starts == 1
        status, out, err = fliss(capsys, "config", "--port", board.path, "--iv", "0x11")
        assert (status, err) == (1, f"fliss: error: --iv: the IV in use is the last "
                                    f"({LAST_IV:#022x}): no IV is above it, so only a new key "
                                    f"can go with a new IV: under one key no IV is used twice "
                                    f"(give a new key)\n")
        status, out, err = fliss(capsys, "config", "--port", board.path, "--mode", "keyed")
        assert (status, err) == (1, f"fliss: error: {used_up}\n")
        with fliss_api.connect(board.path, timeout_s=2.0) as api:
            with pytest.raises(IvsUsedUp) as error:
                api.configure(mode="keyed", mask_width=5)
        assert str(error.value) == used_up
        assert board.model.settings["mask_width"] == 4       # nothing written
        # A new key (with IV 0 again: a new key starts afresh) runs
        status, out, err = fliss(capsys, "config", "--port", board.path, "--mode", "keyed",
                                 "--key", "random", "--iv", "0")
        assert status == 0, err
        with BoardClient(board.path, timeout_s=2.0) as client:
            assert client.status()["ivs_used_up"] == 0
        status, out, err = fliss(capsys, "capture", "--port", board.path, "-o", str(second),
                                 "--acquisitions", "1", "--integration", "1ms")
        assert status == 0 and "warning" not in err, err    # (IV 0, the new key's)
        assert board.starts == 2
