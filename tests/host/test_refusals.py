"""Every ``fliss`` command refuses bad arguments (paths, files, names, numbers) with one error
line and a non-zero status, never a traceback, and before doing any work."""

import subprocess
import sys

import h5py
import pytest

from fliss.host.cli import build_parser, main


def commands():
    """The sub-commands ``fliss --help`` lists."""
    parser = build_parser()
    action, = [action for action in parser._actions if action.dest == "command"]
    return sorted(action.choices)


@pytest.fixture
def files(tmp_path):
    (tmp_path / "file.txt").write_text("text\n")
    (tmp_path / "empty.h5").write_bytes(b"")
    (tmp_path / "latin1.toml").write_bytes("seed = 1  # caf\u00e9\n".encode("latin-1"))
    with h5py.File(tmp_path / "claims.h5", "w") as f:
        f.attrs["format"] = "fliss-capture"
        f.attrs["format_version"] = 2
    with h5py.File(tmp_path / "image.h5", "w") as f:         # an image capture without /image
        f.attrs["format"] = "fliss-capture"
        f.attrs["format_version"] = 3
        f.attrs["mode"] = "image"
        for name in ("identity", "configuration", "histograms", "events", "counters"):
            f.create_group(name)
    return tmp_path


#: Bad arguments of each command; ``{d}`` is a folder holding file.txt, empty.h5, claims.h5
#: (a file that claims the capture format but lacks its groups), image.h5 (an image capture
#: without its /image group), and no-port (nothing). The imager's settings are refused before
#: the port is opened.
CASES = {
    "prf-table": ["--clock 0", "--clock abc", "--prf 0", "--prf 100MHz", "--lengths 1",
                  "--lengths 99", "--mask-widths 40", "--clock inf", "--prf 1e400Hz"],
    "sequence": ["--length 33", "--seed 0", "--seed zz", "--count -1", "--pulse-width 0",
                 "--prf 0", "--seed 0x",
                 # a setting the mode does not read, --grid without --times: not ignored
                 "--mode masked --length 5", "--mode mseq --mask-width 3",
                 "--mode off --key 00", "--mode off --seed 3", "--grid"],
    "demo": ["--out /proc/fliss", "--out {d}/file.txt", "--acquisitions 0", "--integration 10",
             "--integration 0ms", "--target-m -1", "--trace --acquisitions 0", "--trace --out {d}"],
    "reproduce": ["--out /proc/fliss", "--out {d}/file.txt", "--acquisitions 0",
                  "--t-int 5", "--t-int 0s", "--lengths 1", "--mask-widths 0", "--signal -1",
                  "--background xyz", "--jitter x", "--jobs 0"],
    "ports": ["--bogus"],
    "config": ["--port {d}/no-port", "--port {d}", "--port {d}/file.txt", "--port /dev/null",
               "--port {d}/no-port --timeout 0", "--port {d}/no-port --retries -1",
               "--port loop:// --baud -5", "--port {d}/no-port --pixels 60",
               "--port {d}/no-port --pixels 64 --bin-shift 0", "--port {d}/no-port --pixel 64",
               "--port {d}/no-port --pixels 2 --pixel 3", "--port {d}/no-port --first-pixel 64",
               "--port {d}/no-port --collisions maybe", "--port {d}/no-port --depth-filter x",
               "--port {d}/no-port --histogram-format tiny", "--port {d}/no-port --readout x",
               "--port {d}/no-port --depth-threshold -1", "--port {d}/no-port --baud 0"],
    "capture": ["--port {d}/no-port -o /proc/x.h5", "--port {d}/no-port -o {d}",
                "--port {d}/no-port -o {d} --overwrite", "--port {d}/no-port -o /dev/null",
                "--port {d}/no-port -o {d}/file.txt", "--port {d}/no-port -o {d}/none/x.h5",
                "--port {d}/no-port -o {d}/x.h5 --acquisitions 0",
                "--port {d}/no-port -o {d}/x.h5 --integration 0s",
                "--port {d}/no-port -o {d}/x.h5 --readout raw --duration x",
                "--port {d}/file.txt -o {d}/x.h5",
                "--port {d}/no-port -o {d}/x.h5 --readout image --pixels 3",
                "--port {d}/no-port -o {d}/x.h5 --readout depth --pixels 64 --bin-shift 1",
                "--port {d}/no-port -o {d}/x.h5 --readout movie",
                "--port {d}/no-port -o {d}/x.ptu", "--port {d}/no-port -o {d}/x.h5 --shape 2x2"],
    "analyze": ["{d}/nothing.h5", "{d}", "{d}/empty.h5", "{d}/file.txt", "{d}/claims.h5",
                "/dev/null", "{d}/claims.h5 --tolerance x", "{d}/image.h5", "{d}/image.h5 --json",
                "{d}/claims.h5 --json"],
    "plot": ["{d}/claims.h5 -o {d}/a.png", "{d}/file.txt -o {d}/a.png",
             "{d}/nothing.h5 -o /proc/a.png", "{d}/empty.h5 -o {d}", "{d}/claims.h5 -o x.h5",
             "{d}/image.h5 -o {d}/a.png", "{d}/image.h5 -o {d}/a.gif --frames animation",
             "{d}/claims.h5 -o {d}/a.png --frames grid", "{d}/image.h5 -o {d}/a.png --shape 2"],
    "export": ["{d}/nothing.h5 --to ptu -o {d}/x.ptu", "{d}/file.txt --to ptu -o {d}/x.ptu",
               "{d}/claims.h5 --to ptu -o {d}/x.ptu", "{d}/image.h5 --to photon-hdf5 -o {d}/x",
               "{d}/claims.h5 --to csv -o {d}/x", "{d}/claims.h5 --to ptu -o /proc/x.ptu",
               "{d}/claims.h5 --to ptu -o {d}", "{d}/claims.h5 --to ptu -o {d}/file.txt",
               "{d}/claims.h5 --to ptu", "{d}/file.txt --to ptu -o {d}/file.txt --overwrite",
               "{d}/claims.h5 --to ptu -o {d}/x.h5"],
    "view": ["{d}/nothing.h5", "{d}/claims.h5 --port {d}/no-port", "--port {d}/no-port --loop",
             "{d}/claims.h5 --speed inf", "{d}/file.txt --for 1s"],
    "generate": ["--clock 0", "--baud 0", "--clock abc", "--name 1bad", "--name a/b",
                 "--name module", "-o {d}/file.txt", "-o /proc/fliss", "--small --fine-tdc",
                 "--fine-tdc --clock 81MHz", "--tb-mode keyed", "--tb-seed 0",
                 "--tb-seed 0x1_0000_0000", "--tb-length 33", "--tb-mode mseq --tb-length 20",
                 "--tb-mask-width 17", "--tb-pulses 1", "--tb-pulses x", "--name fliss_top_tb",
                 "--fine-tdc --name OSCG", "--clock 1e12Hz"],
    "attack": ["--pulses 0", "--missed 1", "--jitter x", "--sources bogus", "--ghost-m -3",
               "--table /proc/x.txt", "--figure /proc/x.png", "--table {d}",
               "--figure {d}/x.txt",
               # options of sources not asked for; a named file is not replaced unasked
               "--sources masked --keyed-width 3", "--sources mseq,keyed --mask-widths 3",
               "--sources off --key 00", "--table {d}/empty.h5", "--figure {d}/file.txt"],
    "sweep": ["{d}/file.txt -o {d}/out", "{d}/nothing.toml -o {d}/out", "{d}/file.txt -o /proc/x",
              "{d}/file.txt -o {d}/file.txt", "{d}/latin1.toml -o {d}/out"],
    "board": ["--baud 0", "--target-m -1", "--ambient x", "--signal -1", "--reset-after -1",
              "--line-errors 2", "--line-stall-s -1", "--scene square", "--sensor row",
              "--object-m -1", "--scene line --object-m 0", "--scene line --target-m 0",
              "--sim icarus --engine fast", "--engine slow"],
}


def test_the_table_names_only_commands():
    assert set(CASES) <= set(commands())


def _run(capsys, argv):
    try:
        status = main(argv)
    except SystemExit as exit:          # argparse's own refusals
        status = exit.code
    out, err = capsys.readouterr()
    return status, out, err


@pytest.mark.parametrize("command", commands())
def test_bad_arguments_get_one_line_and_no_traceback(command, files, capsys, monkeypatch):
    monkeypatch.chdir(files)
    # A command not in the table (added later) is at least tried with an unknown option.
    for case in CASES.get(command, ["--no-such-option"]):
        argv = [command] + case.format(d=files).split()
        status, out, err = _run(capsys, argv)
        assert status not in (0, None), argv
        assert "Traceback" not in out + err, argv
        errors = [line for line in err.splitlines() if "error:" in line]
        assert len(errors) == 1, (argv, err)
        assert errors[0].startswith(("fliss: error: ", f"fliss {command}: error: ")), argv
        assert err.splitlines()[-1] == errors[0], (argv, err)


def test_the_installed_command_gives_one_line_too(files):
    # Through the real entry point, as a user types it.
    process = subprocess.run([sys.executable, "-m", "fliss", "analyze", str(files / "claims.h5")],
                             capture_output=True, text=True, timeout=120)
    assert (process.returncode, process.stdout) == (1, "")
    assert process.stderr == (f"fliss: error: '{files / 'claims.h5'}' claims the FLISS capture "
                              f"format but is damaged or not written by fliss (no /identity "
                              f"group)\n")
