"""`fliss generate` into a folder it wrote before: the files the earlier run wrote and this one
does not are removed (and said), every other file of the folder stays."""

import pytest

from fliss.host.cli import main
from fliss.host.ip import folder as ip_folder


@pytest.fixture(autouse=True)
def quick_verilog(monkeypatch):
    # The files' list is the subject here, not the Verilog: a module of one line, no Yosys
    monkeypatch.setattr(ip_folder, "convert",
                        lambda top, name, platform=None: f"module {name}; endmodule\n")


def _listing(folder):
    return sorted(path.relative_to(folder).as_posix()
                  for path in folder.rglob("*") if path.is_file())


def test_a_second_generate_removes_what_the_first_wrote_and_it_does_not(tmp_path, capsys):
    folder = tmp_path / "ip"
    assert main(["generate", "-o", str(folder), "--name", "first"]) == 0
    first = capsys.readouterr().out.split()
    (folder / "mine.txt").write_text("the user's own notes\n")
    (folder / "testbench" / "mine.v").write_text("// the user's own bench\n")

    assert main(["generate", "-o", str(folder), "--name", "second", "--no-testbench"]) == 0
    captured = capsys.readouterr()
    second = captured.out.split()

    # The folder holds what the second run printed, the list, and the user's files
    listing = _listing(folder)
    expected = sorted({p.removeprefix(str(folder) + "/") for p in second}
                      | {"mine.txt", "testbench/mine.v", ".fliss-generated"})
    assert listing == expected
    assert "first.v" not in listing and "testbench/commands.hex" not in listing
    # Each removed file is said once, on standard error
    removed = [line for line in captured.err.splitlines() if "removed" in line]
    gone = {p for p in first if p.removeprefix(str(folder) + "/") not in listing}
    assert len(removed) == len(gone) and gone
    assert all(any(path in line for line in removed) for path in gone)
    # The list names exactly the second run's files
    assert sorted((folder / ".fliss-generated").read_text().split()) == \
        sorted(p.removeprefix(str(folder) + "/") for p in second)


def test_a_list_that_points_outside_the_folder_removes_nothing_there(tmp_path, capsys):
    folder = tmp_path / "ip"
    outside = tmp_path / "keep.v"
    outside.write_text("// not generate's\n")
    folder.mkdir()
    (folder / ".fliss-generated").write_text("../keep.v\n/etc/hostname\n\n")
    assert main(["generate", "-o", str(folder), "--no-testbench"]) == 0
    assert outside.read_text() == "// not generate's\n"
    assert "removed" not in capsys.readouterr().err
