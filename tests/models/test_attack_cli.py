"""``fliss attack``: the JSON table on a small budget, and bad options refused in one line."""

import json
import math

import pytest

from fliss.host.cli import main


def test_attack_json_small_budget(capsys):
    code = main(["attack", "--json", "--sources", "off,mseq,masked,keyed",
                 "--lengths", "10", "--mask-widths", "6", "--key", "0123456789abcdef0123",
                 "--pulses", "6e3", "--scene-pulses", "6000", "--acquisition-pulses", "3000",
                 "--no-unknown-taps", "--table", "-", "--figure", "-"])
    assert code == 0
    rows = json.loads(capsys.readouterr().out)
    by_mode = {row["mode"]: row for row in rows}
    assert set(by_mode) == {"off", "mseq", "masked", "keyed"}
    for row in rows:
        assert {"mode", "length", "mask_width", "locked_after_pulses", "ghost_s_db"} <= set(row)
    # Theory (interval mode, 48 checked bits): mseq L=10 one pulse + max(4, ceil(48/10)) checked;
    # masked Wm=6 ceil(32/6) pulses + 8 checked; plus the first pulse, whose delay is unreadable.
    assert by_mode["mseq"]["length"] == 10
    assert by_mode["mseq"]["locked_after_pulses"] == 1 + 1 + 5
    assert by_mode["masked"]["locked_after_pulses"] == 1 + 6 + 8
    assert by_mode["keyed"]["locked_after_pulses"] is None
    # Locked: the ghost is as strong as the victim's own echo (same photons per pulse).
    for mode in ("off", "mseq", "masked"):
        assert abs(by_mode[mode]["ghost_s_db"]) < 3
        assert by_mode[mode]["ghost_reported_fraction"] == 1.0
    # Never locked: the ghost is spread over the range and not reported as a target.
    assert by_mode["keyed"]["ghost_s_db"] > 3 and by_mode["keyed"]["ghost_reported_fraction"] == 0
    assert not any(math.isnan(v) for v in by_mode["off"]["s_db"] if v is not None)


@pytest.mark.parametrize("argv, message", [
    (["--missed", "1.5"], "--missed must be a fraction"),
    (["--pulses", "1.5"], "Pulse count must be a positive whole number"),
    (["--pulses", "lots"], "Pulse count must be a whole number"),
    (["--jitter", "100"], "--jitter 100: give a unit: 10ms or 75ns"),
    (["--jitter", "-1ps"], "--jitter -1ps: time must not be negative, not '-1ps'"),
    (["--ghost-m", "-3"], "--ghost-m must be from 0 to 60 m"),
    (["--sources", "off,lfsr"], "'lfsr' is not one of"),
    (["--lengths", "40"], "L must be from 2 to 32"),
    (["--mask-widths", "x"], "comma-separated integers"),
    (["--key", "xyz"], "--key xyz: A Trivium key is 20 hex digits (80 bits, as the test "
                       "vectors print it) or random, not 'xyz'"),
    (["--key", "12345"], "--key 12345: A Trivium key is 20 hex digits (80 bits, as the test "
                         "vectors print it) or random, not '12345' (5 digits)"),
    (["--iv", "1" * 21], f"--iv {'1' * 21}: A Trivium IV is up to 20 hex digits (80 bits, as the "
                         f"test vectors print it), not '{'1' * 21}' (21 digits)"),
    (["--keyed-width", "17", "--sources", "keyed"], "Mask width must be an integer from 1 to 16"),
    (["--acquisition-pulses", "5000", "--pulses", "100"], "must not exceed"),
])
def test_attack_bad_options(capsys, argv, message):
    assert main(["attack", "--table", "-", "--figure", "-", *argv]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and message in err, err


def test_attack_json_writes_only_what_is_asked(tmp_path, monkeypatch, capsys):
    # With --json the table goes to stdout: no attack.txt nor attack.png in the current folder,
    # only the outputs named.
    monkeypatch.chdir(tmp_path)
    budget = ["--sources", "off", "--pulses", "2000", "--scene-pulses", "2000",
              "--acquisition-pulses", "1000", "--no-unknown-taps"]
    assert main(["attack", "--json", *budget]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [row["mode"] for row in rows] == ["off"]
    assert list(tmp_path.iterdir()) == []
    assert main(["attack", "--json", *budget, "--table", "t.txt"]) == 0
    capsys.readouterr()
    assert sorted(path.name for path in tmp_path.iterdir()) == ["t.txt"]
