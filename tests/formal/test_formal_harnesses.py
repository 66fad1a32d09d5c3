"""Every formal harness and its mutant still elaborate against the gateware as it is (they
reach into blocks for their internal signals, by name), without the formal extra: ``make
test`` finds a renamed signal before ``make formal`` does."""

import pytest

from fliss.formal.runner import checks, discover, prepare


@pytest.mark.parametrize("check", checks(discover().values(), cover=False, mutants=True),
                         ids=lambda check: f"{check.proof.name}-{check.kind}")
def test_harness_elaborates(tmp_path, check):
    folder = prepare(check, build_dir=tmp_path)
    assert "module \\top" in (folder / "design.il").read_text()


def test_a_proof_checks_each_of_its_mutants():
    # keyed.iv_rule has two: the register file's IV rule broken, and the stream wrapping around
    proof = discover()["keyed.iv_rule"]
    assert [(check.label, check.expected) for check in checks([proof], mutants=True)] == [
        ("keyed.iv_rule [proof]", "PASS"), ("keyed.iv_rule [cover]", "PASS"),
        ("keyed.iv_rule [mutant]", "FAIL"), ("keyed.iv_rule [mutant2]", "FAIL")]
