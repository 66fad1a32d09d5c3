"""docs/schemes_section.py: the generated part of docs/interference.md picks, per condition, the
scheme with the fewest failed frames, and says which others its interval cannot tell apart."""

import importlib.util
from pathlib import Path

from fliss.sim.studies.detection import wilson
from fliss.sim.studies.schemes import check_point


_PATH = Path(__file__).resolve().parents[2] / "docs" / "schemes_section.py"
_SPEC = importlib.util.spec_from_file_location("schemes_section", _PATH)
section = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(section)


def _row(failures, frames=100, **point):
    row = check_point(dict(point, frames=frames))
    low, high = wilson(failures, frames)
    row.update(p_failure=failures / frames, p_failure_lo=low, p_failure_hi=high)
    row["label"], row["short"] = section.label(row), section.short(row)
    return row


def test_the_choice_is_the_fewest_failures_and_counts_the_undecided():
    rows = [_row(30, scheme="none"), _row(2, scheme="fliss"), _row(4, scheme="code"),
            _row(0, scheme="fliss", delay_mode="masked")]
    lines = section.choices(rows)
    # masked has 0 of 100 (upper bound 0.037); fliss mseq's 2 of 100 (lower bound 0.0055) and
    # code's 4 (0.016) reach below it; none's 30 (0.22) does not
    assert lines[2] == ("| 1e+05 | FLISS masked: 0.000 (FLISS mseq 0.020 ≈, code 0.040 ≈ within "
                        "the interval) |")


def test_ties_are_named_and_all_equal_is_said():
    rows = [_row(0, scheme="none"), _row(0, scheme="hopping")]
    assert section.choices(rows)[2] == "| 1e+05 | any: all 2 at 0.000 |"
    rows.append(_row(50, scheme="code"))
    assert section.choices(rows)[2] == "| 1e+05 | all but code 0.500: 0.000 |"
    rows.append(_row(1, scheme="fliss"))
    rows.append(_row(3, scheme="fliss", delay_mode="masked"))
    assert section.choices(rows)[2] == ("| 1e+05 | none, hopping: 0.000 (FLISS mseq 0.010 ≈, "
                                        "FLISS masked 0.030 ≈ within the interval) |")


def test_labels_name_the_options_that_differ_from_the_sweep_defaults():
    row = _row(0, scheme="fliss", delay_mode="masked", period_cycles=8000, spads=4,
               coincidence=2)
    assert row["label"] == "FLISS masked Wm=6, 10 kHz, coincidence 2 of 4"
    assert row["short"] == "FLISS masked 10 kHz + 2/4"
