"""The model commands of ``fliss``: output worked out by hand or taken from the paper, and one
clear line for every user mistake."""

import subprocess
import sys

import pytest

from fliss.host.cli import main
from fliss.sim.models.delay import DelayMode, delays


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_sequence_mseq_l3_by_hand(capsys):
    # x^3 + x + 1, Galois right shift (taps 0b101), from state 1:
    # 1 -> 5 -> 7 -> 6 -> 3 -> 4 -> 2 -> 1, so R = state - 1.
    code, out, err = run(capsys, "sequence", "--mode", "mseq", "--length", "3", "--seed", "1",
                         "--count", "8")
    assert code == 0 and err == ""
    assert out.split() == ["0", "4", "6", "5", "2", "3", "1", "0"]


def test_sequence_times(capsys):
    # Interval mode at T = 80: first pulse 1 + R[0] after the first frame, then T + R apart,
    # plus one cycle from fire to the laser edge.
    code, out, _ = run(capsys, "sequence", "--length", "3", "--count", "4", "--times")
    assert code == 0
    delays = [0, 4, 6, 5]
    times, t = [], 0
    for k, r in enumerate(delays):
        t = 1 + r if k == 0 else t + 80 + r
        times.append(t + 1)
    assert [int(v) for v in out.split()] == times


def test_sequence_off_and_masked_range(capsys):
    code, out, _ = run(capsys, "sequence", "--mode", "off", "--count", "3")
    assert out.split() == ["0", "0", "0"]
    code, out, _ = run(capsys, "sequence", "--mode", "masked", "--mask-width", "2",
                       "--seed", "0xabcdef", "--count", "400")
    values = {int(v) for v in out.split()}
    assert values == {0, 1, 2, 3}


def test_prf_table_reproduces_table_2(capsys):
    code, out, _ = run(capsys, "prf-table")
    assert code == 0
    rows = {line.split()[1]: line for line in out.splitlines() if line.startswith("mseq")}
    for length, paper in [(3, "963.9 kHz"), (4, "919.5 kHz"), (5, "842.1 kHz"),
                          (6, "720.7 kHz"), (8, "386.5 kHz")]:
        assert rows[f"L={length}"].count(paper) == 2  # closed form and measured
    assert "2.436 kHz" in rows["L=16"] and "37.25 mHz" in rows["L=32"]


def test_prf_table_other_clock(capsys):
    # 79.5 MHz (iCE40 PLL): T = round(79.5) = 80 cycles, PRF_eff = 79.5 MHz / (80 + 31) for L=6.
    code, out, _ = run(capsys, "prf-table", "--clock", "79.5MHz", "--lengths", "6")
    assert code == 0
    assert f"{79.5e6 / 111 / 1e3:.4g} kHz" in out


def test_prf_table_grid_mode_keeps_nominal_prf(capsys):
    code, out, _ = run(capsys, "prf-table", "--grid", "--lengths", "3", "6",
                       "--mask-widths", "4")
    assert code == 0
    rows = [line for line in out.splitlines() if line.startswith(("mseq", "masked"))]
    assert len(rows) == 3
    assert [row.count("1 MHz") for row in rows] == [2, 2, 1]  # masked: no whole-period measure


@pytest.mark.parametrize("argv, message", [
    (["prf-table", "--grid", "--lengths", "7"],
     "Grid mode needs the largest delay plus the pulse width (126 + 1 cycles)"),
    (["sequence", "--length", "40"], "LFSR length must be an integer from 2 to 32, not 40"),
    (["sequence", "--seed", "0"], "Seed must be an integer from 1 to 63"),
    (["sequence", "--mode", "masked", "--mask-width", "0"],
     "Mask width must be an integer from 1 to 16, not 0"),
    (["sequence", "--prf", "1 MHzz"], "cannot read '1 MHzz' as a frequency"),
    (["sequence", "--count", "-1"], "--count must be from 0 to 16777216 (a line a pulse, made "
                                    "in memory), not -1"),
    (["sequence", "--count", str(1 << 80)], f"--count must be from 0 to 16777216 (a line a "
                                            f"pulse, made in memory), not {1 << 80}"),
    (["sequence", "--grid", "--length", "8", "--times"], "Grid mode needs the largest delay"),
    (["prf-table", "--clock=-80MHz"], "frequency must be positive"),
    (["prf-table", "--clock", "-80MHz"], "--clock -80MHz: frequency must be positive, not "
                                         "'-80MHz'"),
    (["sequence", "--prf", "1"], "--prf 1: give a unit: 80MHz, 1kHz or 1e6Hz"),
    (["prf-table", "--clock", "80e6"], "--clock 80e6: give a unit: 80MHz, 1kHz or 1e6Hz"),
    (["prf-table", "--lengths", "1"], "LFSR length must be an integer from 2 to 32, not 1"),
])
def test_user_errors_are_one_line(capsys, argv, message):
    code, out, err = run(capsys, *argv)
    assert code == 1 and out == ""
    assert err.startswith("fliss: error: ") and message in err
    assert err.count("\n") == 1


def test_module_entry_point():
    result = subprocess.run([sys.executable, "-m", "fliss", "sequence", "--count", "2"],
                            capture_output=True, text=True, timeout=60)
    # Default mseq, L = 6 (x^6 + x + 1, taps 0x21), seed 1: states 1, 33.
    assert result.returncode == 0 and result.stdout.split() == ["0", "32"]
    result = subprocess.run([sys.executable, "-m", "fliss", "sequence", "--seed", "0"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 1 and "Traceback" not in result.stderr


def test_demo_trace(capsys):
    # mseq, L = 4 (x^4 + x^3 + 1), seed 1, at T = 80 cycles: each laser edge T + R after the one
    # before, R from the reference model's sequence.
    code, out, err = run(capsys, "demo", "--trace")
    assert code == 0, err
    lines = out.splitlines()
    assert lines[-1] == "Gateware and reference model agree bit for bit: yes"
    rows = [[int(word) for word in line.split()] for line in lines[2:-1]]
    expected = [int(r) for r in delays(DelayMode.MSEQ, 12, length=4, seed=1)]
    assert [row[:2] for row in rows] == [[index, r] for index, r in enumerate(expected)]
    assert [row[3] for row in rows[1:]] == [80 + r for r in expected[1:]]
    assert [b[2] - a[2] for a, b in zip(rows, rows[1:])] == [80 + r for r in expected[1:]]


def test_ctrl_c_while_the_commands_load_is_one_line(monkeypatch, capsys):
    # Ctrl-C in the first second of `fliss capture` (building the parser imports every command)
    # ended in a KeyboardInterrupt traceback.
    from fliss.host import cli

    def interrupted():
        raise KeyboardInterrupt
    monkeypatch.setattr(cli, "build_parser", interrupted)
    assert cli.main(["capture", "--help"]) == 130
    assert capsys.readouterr() == ("", "fliss: interrupted\n")
