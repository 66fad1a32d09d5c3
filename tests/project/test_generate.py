"""`fliss generate`: the Verilog has exactly the ports that docs/ports.md lists."""

import re
from pathlib import Path

from fliss.host.cli import main


DOCS = Path(__file__).resolve().parents[2] / "docs" / "ports.md"


def documented_ports():
    # The first table of docs/ports.md: the default build's ports
    ports = {}
    for line in DOCS.read_text().split("\n\n| port |")[1].splitlines():
        match = re.match(r"\| `(\w+)` \| (in|out) \| (\d+) \|", line)
        if match:
            ports[match.group(1)] = ("input" if match.group(2) == "in" else "output",
                                     int(match.group(3)))
    return ports


def test_generated_ports_match_the_documentation(tmp_path, capsys, monkeypatch):
    # Without amaranth-boards (as after `pip install fliss`) and without the testbench
    import fliss.boards.constraints

    def no_boards(board):
        raise ImportError("No module named 'amaranth_boards'")
    monkeypatch.setattr(fliss.boards.constraints, "template_family", no_boards)
    assert main(["generate", "-o", str(tmp_path), "--no-testbench"]) == 0
    out, err = capsys.readouterr()
    # The Verilog's path first, then the other files'; what is left out said once
    assert out.splitlines() == [str(tmp_path / name)
                                for name in ("fliss_top.v", "ports.md", "fliss_top.core")]
    assert err == ("fliss: warning: left out constraints templates: they need amaranth-boards "
                   "(pip install 'fliss[boards]')\n")
    core = (tmp_path / "fliss_top.core").read_text()
    assert "  lint:\n" in core and "sim:" not in core and "testbench" not in core
    path = tmp_path / "fliss_top.v"
    text = path.read_text()
    top = text[text.index("module fliss_top("):]
    top = top[:top.index("endmodule")]
    ports = {}
    for direction, width, name in re.findall(r"^\s*(input|output)\s+(?:\[(\d+):0\]\s+)?(\w+);",
                                             top, flags=re.MULTILINE):
        ports[name] = (direction, int(width) + 1 if width else 1)
    assert ports == documented_ports()


def test_generate_refuses_a_bad_baud(tmp_path, capsys):
    assert main(["generate", "-o", str(tmp_path), "--baud", "21M"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("fliss: error: Baud rate 21000000 cannot be met within 2%")
