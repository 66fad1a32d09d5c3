"""``fliss board`` without running a simulation: the per-user cache its builds go to, the
engine its options choose, what it says before a build and after Ctrl-C, the links of boards
that were killed; and the model board's options of ``fliss board``."""

import math
import os

import pytest

from fliss.host import cache
from fliss.host.cli import main
from fliss.host.errors import VirtualBoardError
from fliss.host.virtual import VirtualBoard, board_folder, build_key
from fliss.sim.benches.runner import simulator_available


needs_verilator = pytest.mark.skipif(not simulator_available("verilator"),
                                     reason="Verilator is missing")


def test_the_cache_is_per_user_and_movable(monkeypatch, tmp_path):
    monkeypatch.delenv("FLISS_CACHE_DIR", raising=False)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache.build_root() == tmp_path / "home" / ".cache" / "fliss" / "virtual-board"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.build_root() == tmp_path / "xdg" / "fliss" / "virtual-board"
    monkeypatch.setenv("FLISS_CACHE_DIR", str(tmp_path / "mine"))
    assert cache.build_root() == tmp_path / "mine" / "virtual-board"
    # Whatever the working folder: never the checkout's build/
    monkeypatch.chdir(tmp_path)
    board = VirtualBoard("icarus", engine="cocotb")
    assert board.folder.parent == tmp_path / "mine" / "virtual-board"


def test_builds_of_other_options_never_share_a_folder(tmp_path):
    folders = {board_folder(tmp_path, "cocotb", "verilator", **options)
               for options in ({}, {"baud": 9600}, {"fine_tdc": True}, {"small": True})}
    folders.add(board_folder(tmp_path, "cocotb", "icarus"))
    assert len(folders) == 5
    # Named by what runs and the key of the gateware and options
    key = build_key("verilator", fine_tdc=True)
    assert board_folder(tmp_path, "cocotb", "verilator", fine_tdc=True) == \
        tmp_path / f"verilator-fine-{key[:16]}"


def test_a_build_of_another_environment_is_not_reused(tmp_path, monkeypatch):
    # A Verilator build loads cocotb's libraries from the folder it was linked against: after
    # the environment is made again elsewhere (or removed), that build cannot start
    import cocotb_tools.config
    here = board_folder(tmp_path, "cocotb", "verilator")
    monkeypatch.setattr(cocotb_tools.config, "libs_dir", tmp_path / "other-venv" / "libs")
    assert board_folder(tmp_path, "cocotb", "verilator") != here


def test_a_build_unused_for_long_is_removed(tmp_path):
    old, recent = tmp_path / "verilator-0123", tmp_path / "fast-4567"
    for folder in (old, recent):
        folder.mkdir()
        cache.touch(folder)
    long_ago = os.stat(old / "last-used").st_mtime - (cache.STALE_DAYS + 1) * 86400
    os.utime(old / "last-used", (long_ago, long_ago))
    assert cache.prune(tmp_path) == [old]
    assert not old.exists() and recent.exists()


def test_the_link_of_a_killed_board_is_removed(tmp_path):
    (tmp_path / "tty-2").symlink_to(tmp_path / "gone")     # a board killed with -9
    master, slave = os.openpty()
    try:
        (tmp_path / "tty").symlink_to(os.ttyname(slave))  # a board still running
        assert cache.remove_stale_links(tmp_path) == ["tty-2"]
        assert not os.path.lexists(tmp_path / "tty-2") and (tmp_path / "tty").exists()
    finally:
        os.close(master)
        os.close(slave)


@pytest.mark.parametrize("options", [{"fine_tdc": True}, {"small": True},
                                     {"jumper": "laser"}])
def test_the_options_choose_the_engine_that_runs_them(options):
    assert VirtualBoard("verilator", **options).engine == "cocotb"


@needs_verilator
def test_a_build_is_announced_and_ctrl_c_during_it_is_not_a_clean_stop(monkeypatch, tmp_path,
                                                                       capsys):
    def interrupted_build(self, **options):
        raise KeyboardInterrupt

    monkeypatch.setenv("FLISS_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(VirtualBoard, "start", interrupted_build)
    assert main(["board", "--engine", "cocotb", "--baud", "9600"]) == 130
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("fliss: building the virtual board (verilator, cocotb engine, "
                             "9600 baud), once for this gateware and these options: some "
                             f"minutes; cached in {tmp_path / 'virtual-board' / 'verilator-'}")
    assert err[-1] == "fliss: interrupted before the virtual board started (its build, if one " \
                      "was under way, is left unfinished and made again next time)"


@needs_verilator
def test_a_baud_rate_the_gateware_cannot_make_is_refused_before_a_build(monkeypatch, tmp_path,
                                                                        capsys):
    from fliss.hdl.clock import DEFAULT_CLOCK_HZ
    from fliss.hdl.clock import bit_cycles
    with pytest.raises(ValueError) as caught:
        bit_cycles(DEFAULT_CLOCK_HZ, 100_000_000)
    monkeypatch.setenv("FLISS_CACHE_DIR", str(tmp_path))
    assert main(["board", "--engine", "cocotb", "--baud", "100M"]) == 1
    assert capsys.readouterr().err == f"fliss: error: {caught.value}\n"
    assert not (tmp_path / "virtual-board").exists()


@pytest.mark.parametrize("option", ["target_m", "object_m", "ambient_hz", "signal",
                                    "aggressor_signal"])
def test_a_scene_quantity_beyond_any_number_is_refused_before_a_build(option):
    # `fliss board --target-m 1e400` (inf) had started the build and the board, whose scene then
    # stopped it: the model board refuses it at once, and so must the virtual board.
    for value in (math.inf, math.nan, -1.0):
        with pytest.raises(VirtualBoardError, match="must be a finite number, not negative"):
            VirtualBoard("verilator", **{option: value})
