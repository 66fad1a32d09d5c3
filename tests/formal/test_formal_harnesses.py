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
