"""Every ``fliss`` command example of the README, of ``docs/*.md`` and of the ``--help`` texts
parses with the current command line, and runs (in this process, through
:func:`fliss.host.cli.main`) against Python model boards, unless :data:`PARSE_ONLY` says why
not. The examples are found by ``tests/project/doc_examples.py``; a fenced block reads as a
session (its ``config`` and ``capture`` examples run first, in order, before each later one).

What a run changes from the example as written, all in the tables below: the docs' ports are
model boards (:data:`BOARDS`), files are written in a fresh folder per case, an example's
missing required arguments are filled in (:data:`FILL`), missing input files are captured
first (:data:`INPUTS`), long runs are shortened (:data:`SHORTER`). A run must exit 0 and show
what the docs say it shows (:data:`CHECKS`); examples that fail by a known bug are in
:data:`KNOWN_BUGS` (strict xfail: they turn into failures when the bug is fixed). The
messages the docs quote are checked in ``test_doc_messages.py``.
"""

import contextlib
import io
import json
import re
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from doc_examples import DOCS, ROOT, all_examples, cases, positionals, subparsers
from fliss.host.cli import main, parse_args
from fliss.host.commands.view_options import VIEW_FLAGS
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene, line_pixels


EXAMPLES = all_examples()
CASES = cases(EXAMPLES)

#: The model board behind each port the docs name: the single-pixel scene, or the line scene of
#: the demo's imager part (its second board, ``/dev/pts/M``).
BOARDS = {"/dev/pts/N": "single", "/dev/ttyUSB0": "single", "/dev/ttyUSB1": "single",
          "/dev/pts/M": "line"}
SCENES = {"single": Scene(detections_per_pulse=0.1, background_hz=1e5),
          "line": Scene(pixels=line_pixels(), detections_per_pulse=0.02, background_hz=1e4)}

#: Required arguments an example leaves out (a command named in prose, ``...`` in a sketch),
#: given so that the rest of it can be checked and run.
FILL = {
    "config": {"--port": ["/dev/pts/N"]},
    "selftest": {"--port": ["/dev/pts/N"]},
    "calibrate": {"--port": ["/dev/pts/N"]},
    "capture": {"--port": ["/dev/pts/N"], "--output": ["capture.h5"]},
    "analyze": {"files": ["capture.h5"]},
    "plot": {"files": ["capture.h5"], "--output": ["plot.png"]},
    "sweep": {"spec": ["examples/sweep-quick.toml"], "--out": ["sweep"]},
    "export": {"capture": ["raw.h5"], "--to": ["ptu"], "--output": ["export.ptu"]},
}
#: ... where an example needs another input than FILL's: the shape 8x8 is of 64 pixels.
FILL_OF = {"fliss plot --help: --shape 8x8": {"files": ["depth.h5"]}}

#: Capture files that examples read and no example above them wrote: how they are made (a
#: ``fliss capture`` on the board named first).
INPUTS = {
    "capture.h5": ["capture", "--port", "/dev/pts/N", "--integration", "2ms",
                   "--acquisitions", "2"],
    "run.h5": ["capture", "--port", "/dev/pts/N", "--integration", "2ms", "--acquisitions", "2"],
    "raw.h5": ["capture", "--port", "/dev/pts/N", "--readout", "raw", "--duration", "20ms"],
    "depth.h5": ["capture", "--port", "/dev/pts/M", "--readout", "depth", "--pixels", "64",
                 "--bin-shift", "6", "--integration", "2ms", "--acquisitions", "2"],
}

#: Recordings of other instruments that examples read: copies of the samples the readers' tests
#: use (tests/host/data/tttr/, with their sources and licences).
SAMPLES = {"run.ht3": "hydraharp_v10.ht3", "FILE.ht3": "hydraharp_v10.ht3"}
SAMPLE_FOLDER = Path(__file__).resolve().parents[1] / "host" / "data" / "tttr"

#: Folders an example expects to exist: the README's demo commands write into the folder that
#: ``fliss demo`` makes for its files.
FOLDERS = ("build/demo",)

#: Long runs made short: per command, options set (added or replaced) to run it in seconds.
SHORTER = {
    # 50 000 observed pulses (the default) take about 20 s, 10^6 pulses 80 s; in 6000 pulses,
    # as in `fliss demo`, the attacker locks onto every predictable source (it takes tens of
    # pulses) and the histograms still show the ghost.
    "attack": {"--pulses": "6000", "--scene-pulses": "6000", "--acquisition-pulses": "3000"},
    # The live view serves until Ctrl-C: a second of it, on a free port (runs in parallel).
    "view": {"--for": "1s", "--view-port": "0"},
    "capture": {"--view-port": "0"},       # with --view only
}

#: Examples that are only parsed, and why: (command, a word of the example or "", reason);
#: the first entry that matches decides (a reason of None: it runs).
PARSE_ONLY = [
    ("demo", "--trace", None),
    ("demo", "", "builds and runs two virtual boards in Verilator: minutes (make demo runs it)"),
    ("board", "", "builds the gateware for Verilator (about a minute), then serves it until "
                  "Ctrl-C; tests/boards/test_virtual_board.py runs it"),
    ("generate", "", "elaborates the whole top level to Verilog (about 10 s); "
                     "tests/project/test_generate.py and tests/project/test_generate_ip.py run it"),
    ("sweep", "--scheduler", "needs a Dask scheduler running at that address"),
    ("sweep", "big.toml", "stands for a spec of the reader's own: not in the repository"),
    ("reproduce", "--quick", None),
    ("reproduce", "", "the paper's 300 acquisitions per setting, or other counts: the same "
                      "experiments as --quick, which runs"),
    ("selftest", "", "needs a board with a loopback; tests/boards/test_selftest.py runs it on the "
                     "model board's"),
    ("calibrate", "", "needs a board whose fine TDC has a delay line; "
                      "tests/boards/test_selftest.py runs it on the model board's loopback"),
    ("view", "--port", None),
    ("view", "run.h5", None),
    ("view", "", "names neither a board nor a file: the examples that do run"),
]

#: Examples that fail by a bug being fixed elsewhere: where (the case id) -> the bug.
KNOWN_BUGS = {}


def parse_only_reason(argv):
    for command, word, reason in PARSE_ONLY:
        if argv[0] == command and (not word or word in argv):
            return reason
    return None


def filled(example, argv):
    """``argv`` with the required arguments it leaves out (:data:`FILL`)."""
    subparser = subparsers()[argv[0]]
    given = set(argv[1:])
    fill = {**FILL.get(argv[0], {}), **FILL_OF.get(example.where, {})}
    if argv[0] == "export" and "photon-hdf5" in argv:
        fill["--output"] = ["export.hdf5"]      # (a name of the format's: others are refused)
    out = list(argv)
    for action in subparser._actions:
        if action.option_strings:
            if action.required and not given & set(action.option_strings):
                key = next((s for s in action.option_strings if s in fill), None)
                assert key, f"FILL has no {action.option_strings[0]} for fliss {argv[0]}"
                out += [key, *fill[key]]
        elif action.nargs not in ("?", "*") and not positionals(argv[0], argv[1:]):
            assert action.dest in fill, f"FILL has no {action.dest} for fliss {argv[0]}"
            out += fill[action.dest]
    return out


# The tests

@pytest.mark.parametrize("example, argv", [(e, a) for _, e, a in CASES],
                         ids=[id_ for id_, _, _ in CASES])
def test_example_parses(example, argv, monkeypatch):
    monkeypatch.delenv("FLISS_PORT", raising=False)
    if example.mention is not None:
        # a command's option named in prose: it exists
        assert example.mention in subparsers()[argv[0]]._option_string_actions
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr):
        try:
            parse_args(filled(example, argv))
        except SystemExit:
            pytest.fail(f"{example.where}: `{example.text}` does not parse: "
                        f"{stderr.getvalue().strip()}")


def test_examples_found_everywhere():
    """The collector sees the examples of every file that has some, and of the help texts."""
    wheres = {e.where.split(":")[0] for e in EXAMPLES}
    with_examples = {path.relative_to(ROOT).as_posix() for path in DOCS
                     if re.search(r"`(\$ )?(\.venv/bin/)?fliss \w|^(\$ )?(\.venv/bin/)?fliss \w",
                                  path.read_text(), flags=re.MULTILINE)}
    assert with_examples <= wheres
    assert {"fliss plot --help", "fliss config --help"} <= wheres
    assert len(CASES) > 100


def test_tables_name_collected_examples():
    """No entry of a table outlives its example."""
    assert set(KNOWN_BUGS) <= {id_ for id_, _, _ in CASES}
    assert set(FILL_OF) <= {e.where for e in EXAMPLES}
    argvs = [filled(example, argv) for _, example, argv in CASES]
    for command, word, _ in PARSE_ONLY:
        assert any(argv[0] == command and (not word or word in argv) for argv in argvs), \
            (command, word)
    assert set(SHORTER) <= {argv[0] for argv in argvs}


@pytest.fixture(scope="module")
def boards():
    with model_board(scene=SCENES["single"]) as single, \
            model_board(scene=SCENES["line"]) as line:
        yield {"single": single, "line": line}


@pytest.fixture
def workdir(tmp_path, monkeypatch, boards):
    """A fresh folder to run in (examples/ as in the repository; FOLDERS made), the boards just
    powered on."""
    monkeypatch.delenv("FLISS_PORT", raising=False)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    for folder in FOLDERS:
        (tmp_path / folder).mkdir(parents=True)
    for board in boards.values():
        board.reset()
    return tmp_path


def on_boards(argv, boards):
    """``argv`` with each port of the docs replaced by its model board's pty."""
    out = list(argv)
    for i in range(len(argv) - 1):
        if argv[i] == "--port":
            out[i + 1] = boards[BOARDS[argv[i + 1]]].path
    return out


def shorter(argv):
    out = list(argv)
    if argv[0] == "capture" and "--view" not in argv:
        if not VIEW_FLAGS.keys() & {arg[2:].replace("-", "_") for arg in argv}:
            return out      # (the view's options are refused without --view)
        out.append("--view")
        if "--shape" in argv:
            out += ["--pixels", "64", "--bin-shift", "3", "--acquisitions", "2"]  # 8x8: 64
    for option, value in SHORTER.get(argv[0], {}).items():
        if option in out:
            out[out.index(option) + 1] = value
        else:
            out += [option, value]
    return out


def fliss(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def make_inputs(argv, boards, capsys):
    """Capture the input files of an ``analyze``, ``plot``, ``export`` or ``view`` that are not
    there (INPUTS)."""
    if argv[0] not in ("analyze", "plot", "export", "view"):
        return
    for name in positionals(argv[0], argv[1:]):
        if not Path(name).exists() and name in SAMPLES:
            Path(name).write_bytes((SAMPLE_FOLDER / SAMPLES[name]).read_bytes())
        elif not Path(name).exists():
            code, _, err = fliss(on_boards([*INPUTS[name], "-o", name], boards), capsys)
            assert code == 0, f"making the input {name}: {err}"


#: What a run shows, as the docs say: per command, a function of (example, argv, stdout).
CHECKS = {}


def check(command):
    def register(function):
        CHECKS[command] = function
        return function
    return register


RUN_CASES = [pytest.param(example, argv, id=id_,
                          marks=[pytest.mark.xfail(strict=True, reason=KNOWN_BUGS[id_])]
                          if id_ in KNOWN_BUGS else [])
             for id_, example, argv in CASES
             if example.mention is None and parse_only_reason(filled(example, argv)) is None]

_RUNS = {}


def _same_run(argv):
    """``argv`` as a key: runs that differ only in the order of their options, the name of their
    output, or options given their default value, are the same run."""
    options = subparsers()[argv[0]]._option_string_actions
    given, positional = [], []
    for token in argv[1:]:
        if token in options:
            given.append([options[token].dest])
        elif given and options.get(token) is None and _takes_more(options, given[-1]):
            given[-1].append(token)
        else:
            positional.append(token)
    key = set()
    for dest, *values in given:
        action = next(a for a in options.values() if a.dest == dest)
        if dest in ("output", "out"):
            values = ["<output>"]
        elif values == [str(action.default)]:
            continue
        key.add((dest, *values))
    return argv[0], tuple(positional), frozenset(key)


def _takes_more(options, group):
    action = next(a for a in options.values() if a.dest == group[0])
    taken = len(group) - 1
    return {None: 1, "?": 1, "*": taken + 1, "+": taken + 1}.get(action.nargs, action.nargs) > taken


@pytest.mark.parametrize("example, argv", RUN_CASES)
def test_example_runs(example, argv, boards, workdir, capsys):
    for step in example.before:
        code, _, err = fliss(on_boards(filled(example, step), boards), capsys)
        assert code == 0, f"{' '.join(step)}: {err}"
    argv = shorter(filled(example, argv))
    # The same run for another example (a command named in prose, written out elsewhere) is not
    # run again: what it showed is checked again.
    key = (tuple(map(tuple, example.before)), _same_run(argv))
    if key not in _RUNS:
        make_inputs(argv, boards, capsys)
        _RUNS[key] = (*fliss(on_boards(argv, boards), capsys), argv, workdir)
    code, out, err, argv, folder = _RUNS[key]
    assert code == 0, err
    if argv[0] in CHECKS:
        CHECKS[argv[0]](example, argv, out, folder)


# What the runs show

def _value(argv, option, default=None):
    return argv[argv.index(option) + 1] if option in argv else default


def _output(argv):
    return next(argv[i + 1] for i, token in enumerate(argv) if token in ("-o", "--output", "--out"))


@check("capture")
def _capture_wrote_its_file(example, argv, out, folder):
    from fliss.host.fileformat import read_capture
    path = folder / _output(argv)
    assert read_capture(path).complete.any()


@check("plot")
def _plot_wrote_a_png(example, argv, out, folder):
    path = folder / _output(argv)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@check("analyze")
def _analyze_json_per_file(example, argv, out, folder):
    # --json: "a list, one object per file"
    if "--json" in argv:
        files = positionals("analyze", argv[1:])
        assert len(json.loads(out)) == len(files)


@check("sequence")
def _sequence_one_line_per_pulse(example, argv, out, folder):
    # "One delay in clock cycles per line"
    values = out.split()
    assert len(values) == int(_value(argv, "--count", "16"))
    assert all(value.isdigit() for value in values)


#: Delay sources an attacker predicts, and those it never locks onto (docs/security.md).
PREDICTED, NEVER_LOCKED = ("off", "mseq", "masked"), ("keyed", "random")


@check("attack")
def _attack_locks_onto_what_it_predicts(example, argv, out, folder):
    sources = _value(argv, "--sources", "off,mseq,masked,keyed,random").split(",")
    if "--json" in argv:
        locked = {row["label"]: row["locked_after_pulses"] for row in json.loads(out)}
    else:
        rows = re.findall(r"^(\w+(?: \w+=\d+)?) +\d+ +(\d+|never) ", out, flags=re.MULTILINE)
        locked = {label: None if after == "never" else int(after) for label, after in rows}
    assert sorted({label.split()[0] for label in locked}) == sorted(sources)
    for label, after in locked.items():
        if label.split()[0] in NEVER_LOCKED:
            assert after is None, label
        else:
            assert after is not None, label


@check("sweep")
def _sweep_results(example, argv, out, folder):
    import tomllib
    spec = tomllib.loads((ROOT / positionals("sweep", argv[1:])[0]).read_text())
    points = 1
    for value in spec["parameters"].values():
        points *= len(value) if isinstance(value, list) else 1
    table = pq.read_table(folder / _output(argv) / "results.parquet")
    assert table.num_rows == points
    said = re.search(r"# (\d+) points", example.text)
    if said:
        assert int(said.group(1)) == points
    assert len(list((folder / _output(argv)).glob("*.png"))) == 3     # three PNG figures


@check("reproduce")
def _reproduce_results(example, argv, out, folder):
    # docs/results.md: results.md, results.csv and fig07_victim.png ... fig12_suppression_Wm.png
    results = folder / _value(argv, "--out", "fliss-results")
    names = {path.name for path in results.iterdir()}
    assert {"results.md", "results.csv", "fig07_victim.png", "fig12_suppression_Wm.png"} <= names
    assert len([name for name in names if re.fullmatch(r"fig(0[7-9]|1[0-2])_\w+\.png", name)]) == 6


@check("demo")
def _trace_is_the_scheduler(example, argv, out, folder):
    # each pulse T + R cycles after the previous (T = 80 cycles: 1 MHz at 80 MHz), and the
    # gateware agrees with the model
    lines = out.splitlines()
    rows = [[int(word) for word in line.split()] for line in lines if re.fullmatch(r"[\d ]+", line)]
    assert len(rows) == 12
    for (_, _, previous), (_, delay, edge, interval) in zip(
            [row[:3] for row in rows], rows[1:]):
        assert interval == edge - previous == 80 + delay
    assert lines[-1] == "Gateware and reference model agree bit for bit: yes"
