"""``fliss reproduce`` on a tiny run: files written, and the suppression grows with L."""

import csv
import math

import pytest

from fliss.host.cli import main


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    code = main(["-q", "reproduce", "--acquisitions", "4", "--t-int", "20ms", "--lengths", "3",
                 "6", "--mask-widths", "6", "--jobs", "1", "--out", str(out)])
    return code, out


def test_tiny_reproduction_writes_every_output(tiny_run):
    code, out = tiny_run
    assert code == 0
    for name in ("results.csv", "results.md", "fig07_victim.png", "fig08_aggressor.png",
                 "fig09_suppression_L.png", "fig10_histograms.png", "fig11_deviations.png",
                 "fig12_suppression_Wm.png"):
        assert (out / name).stat().st_size > 0, name
    text = (out / "results.md").read_text()
    assert "35 dB" in text and "50 dB" in text and "132.1 ns" in text


def test_suppression_grows_with_the_lfsr_length(tiny_run):
    _, out = tiny_run
    with open(out / "results.csv") as file:
        rows = list(csv.DictReader(file))
    s = {row["setting"]: float(row["s_db"]) for row in rows if row["setting"].startswith("L =")}
    off = next(float(row["s_db"]) for row in rows if row["experiment"].startswith("aggressor"))
    assert off < s["L = 3"] < s["L = 6"]
    # Victim ToF measured near 2 z / c = 26.69 ns in every setting
    for row in rows:
        assert float(row["tof_ns"]) == pytest.approx(2 * 4.0 / 299_792_458 * 1e9, abs=0.5)
    # Table 2: PRF_eff = 80 MHz / (80 + 2**(L-1) - 1)
    prf = {row["setting"]: float(row["prf_eff_khz"]) for row in rows}
    assert prf["L = 3"] == pytest.approx(80e3 / 83, rel=1e-6)
    assert prf["L = 6"] == pytest.approx(80e3 / 111, rel=1e-6)
    assert all(math.isfinite(float(row["s_db"])) for row in rows
               if not row["experiment"].startswith("victim"))


@pytest.mark.parametrize("argv, message", [
    (["--acquisitions", "0"], "--acquisitions must be at least 1, not 0"),
    (["--t-int", "5"], "--t-int: give a unit: 10ms or 75ns"),
    (["--lengths", "40"], "--lengths must be from 2 to 16 (complete sequences), not 40"),
    (["--mask-widths", "17"], "Mask width must be an integer from 1 to 16, not 17"),
    (["--jobs", "0"], "--jobs must be at least 1, not 0"),
])
def test_user_mistakes_give_one_line_and_exit_1(argv, message, capsys, tmp_path):
    assert main(["reproduce", "--out", str(tmp_path)] + argv) == 1
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"fliss: error: {message}"


def test_two_workers_on_the_sweep_engine_give_the_same_table(tiny_run, tmp_path):
    _, out = tiny_run
    code = main(["-q", "reproduce", "--acquisitions", "4", "--t-int", "20ms", "--lengths", "3",
                 "6", "--mask-widths", "6", "--jobs", "2", "--no-figures", "--out", str(tmp_path)])
    assert code == 0
    assert (tmp_path / "results.csv").read_text() == (out / "results.csv").read_text()
