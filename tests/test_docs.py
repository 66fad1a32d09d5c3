"""The register table of docs/protocol.md says what hdl/registers.py defines."""

import re
from pathlib import Path

from fliss.hdl.registers import REGISTERS


DOC = Path(__file__).resolve().parent.parent / "docs" / "protocol.md"


def test_register_table_matches_the_register_map():
    rows = re.findall(r"^\| `0x([0-9a-f]+)` \| `(\w+)` \| (\d+) \| (\d+) … (\d+) \| (\d+) \|",
                      DOC.read_text(), flags=re.MULTILINE)
    documented = [(int(a, 16), name, int(bits), int(lo), int(hi), int(reset))
                  for a, name, bits, lo, hi, reset in rows]
    defined = [(r.address, r.name, r.width, r.minimum, r.maximum, r.reset_value(80_000_000))
               for r in REGISTERS]
    assert documented == defined
