"""docs/protocol.md says what hdl/registers.py and hdl/protocol.py define: the register table,
the header and every payload layout."""

import re
from pathlib import Path

from amaranth.lib import data

from fliss.hdl.event import Event
from fliss.hdl.protocol import (GATEWARE_VERSION, GATEWARE_MAJOR, GATEWARE_MINOR, GATEWARE_PATCH,
                                PROTOCOL_VERSION, CHUNK_BINS, Header, Ack, Nak,
                                Identity, ReadRequest, Status, HistogramChunk, HistogramCompact,
                                registers_layout, READ_MAX, CONSISTENCY, EVENT_BYTES, COMPACT_BYTES,
                                DepthHeader, DepthRecord, DEPTH_HEADER_BYTES, DEPTH_RECORD_BYTES,
                                MAX_PAYLOAD)
from fliss.hdl.registers import REGISTERS


DOC = Path(__file__).resolve().parents[2] / "docs" / "protocol.md"


def _register_row(register):
    # The line of the register table that says what the register map's row says
    flags = ", ".join(f"`--{keyword.name.replace('_', '-')}`" for keyword in register.keywords)
    return (f"| `0x{register.address:02x}` | `{register.name}` | {register.width} | "
            f"{register.minimum} … {register.maximum} | {register.reset_value(80_000_000)} | "
            f"{register.unit} | {flags} | {register.doc} |")


def test_register_table_matches_the_register_map():
    # Every column of every row: address, name, width, range, reset, unit, flags and meaning
    documented = re.findall(r"^\| `0x[0-9a-f]+` \| `\w+` \|.*$", DOC.read_text(),
                            flags=re.MULTILINE)
    defined = [_register_row(register) for register in REGISTERS]
    assert documented == defined, "docs/protocol.md's register table should read:\n" + \
        "\n".join(defined)


def _payload_tables():
    # {heading name: [(offset, size, field)]} from the payload tables under "## Payloads".
    text = DOC.read_text().split("## Payloads\n", 1)[1].split("\n## ", 1)[0]
    tables = {}
    for section in text.split("\n### ")[1:]:
        name = re.match(r"`([^`]+)`", section).group(1)
        rows = re.findall(r"^\| (\d+) \| (\d+)( × n)? \| `(\w+)` \|", section, flags=re.MULTILINE)
        tables[name] = [(int(offset), int(size), field) for offset, size, _, field in rows]
    return tables


def test_payload_tables_match_the_layouts():
    layouts = {"Ack": Ack, "Nak": Nak, "Identity": Identity, "ReadRequest": ReadRequest,
               "registers_layout(n)": registers_layout(1), "Status": Status,
               "HistogramChunk": HistogramChunk, "HistogramCompact": HistogramCompact,
               "Event": Event, "DepthHeader": DepthHeader, "DepthRecord": DepthRecord}
    tables = _payload_tables()
    assert sorted(tables) == sorted(layouts)
    for name, layout in layouts.items():
        # (these tables count bits, the others bytes)
        unit = 1 if name in ("Event", "HistogramChunk", "HistogramCompact", "DepthRecord") else 8
        defined = [(field.offset // unit, field.width // unit, field_name)
                   for field_name, field in data.Layout.cast(layout)]
        assert all(field.offset % unit == 0 and field.width % unit == 0
                   for _, field in data.Layout.cast(layout)), name
        assert tables[name] == defined, name


def test_payload_limits_in_the_text():
    text = DOC.read_text()
    assert f"`READ_MAX = {READ_MAX}`" in text
    assert f"`EVENT_BYTES = {EVENT_BYTES}`" in text
    assert f"`PROTOCOL_VERSION = {PROTOCOL_VERSION}`" in text
    assert f"`CHUNK_BINS` = {CHUNK_BINS}" in text
    assert f"`COMPACT_BYTES` = {COMPACT_BYTES}" in text
    assert f"`CONSISTENCY = {CONSISTENCY:#06x}`" in text
    assert f"`MAX_PAYLOAD = {MAX_PAYLOAD}`" in text
    assert f"`DEPTH_HEADER_BYTES = {DEPTH_HEADER_BYTES}`" in text
    assert f"`DEPTH_RECORD_BYTES = {DEPTH_RECORD_BYTES}`" in text


def test_packet_header_table_matches_the_header():
    rows = re.findall(r"^\| (\d+) +\| (\d+) +\| `(\w+)` +\|", DOC.read_text().split(
        "## Packet\n", 1)[1].split("\n## ", 1)[0], flags=re.MULTILINE)
    documented = [(int(offset), int(size), name) for offset, size, name in rows]
    assert documented == [(field.offset // 8, field.width // 8, name)
                          for name, field in data.Layout.cast(Header)]


def test_gateware_version_is_the_package_version():
    # The version is written once, in fliss/__init__.py; pyproject.toml reads it from there.
    pyproject = (DOC.parent.parent / "pyproject.toml").read_text()
    assert re.search(r'^dynamic = \["version"\]', pyproject, flags=re.MULTILINE)
    assert 'version = {attr = "fliss.__version__"}' in pyproject
    init = (DOC.parent.parent / "fliss" / "__init__.py").read_text()
    written = re.findall(r'^__version__ = "([^"]+)"', init, flags=re.MULTILINE)
    assert written == [GATEWARE_VERSION]
    major, minor, patch = (int(part) for part in GATEWARE_VERSION.split("."))
    assert (GATEWARE_MAJOR, GATEWARE_MINOR, GATEWARE_PATCH) == (major, minor, patch)