"""``fliss sweep``: specs, determinism across worker counts, resuming, the command, Ctrl-C."""

import os
import re
import signal
import subprocess
import sys
import time

import psutil
import pyarrow.parquet as pq
import pytest

import sweep_points
from fliss.host.cli import main
from fliss.host.sweep.engine import (Store, SweepError, cluster, compute, run_sweep,
                                              table_rows, write_table)
from fliss.host.sweep.spec import SpecError, load, parse, point_key, point_seed


MODEL = "sweep_points:evaluate"
TESTS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(TESTS))


@pytest.fixture(scope="module")
def client():
    """One LocalCluster of two worker threads for the module (starting one costs a second)."""
    with cluster(2, processes=False) as client:
        yield client


def grid(**parameters):
    return parse({"model": MODEL, "seed": 11, "parameters": parameters}, "grid.toml")


def table(path):
    return pq.read_table(path).to_pylist()


# Specs -----------------------------------------------------------------------------------------

def test_grid_is_the_product_of_lists_and_zip_groups_with_defaults_filled():
    spec = parse({"model": MODEL, "seed": 3, "frames": 20,
                  "parameters": {"scheme": ["off", "mseq"], "t_int_s": 0.01},
                  "zip": {"power": {"aggressors": [1, 4, 8], "aggressor_power_db": [0.0, 3.0,
                                                                                    6.0]}}},
                 "spec.toml")
    points = spec.points()
    assert len(points) == 2 * 3
    assert {(p["scheme"], p["aggressors"], p["aggressor_power_db"]) for p in points} == \
        {(s, a, w) for s in ("off", "mseq") for a, w in ((1, 0.0), (4, 3.0), (8, 6.0))}
    assert all(p["frames"] == 20 and p["t_int_s"] == 0.01 and p["sleep_s"] == 0.0
               for p in points)
    assert spec.varied() == ["scheme", "aggressors", "aggressor_power_db"]


def test_spec_file_is_read(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(f'model = "{MODEL}"\nseed = 5\n[parameters]\naggressors = [1, 2]\n')
    spec = load(path)
    assert (spec.seed, len(spec.points()), spec.path) == (5, 2, str(path))


@pytest.mark.parametrize("data, message", [
    ({"sed": 1}, "s.toml: sed: unknown key (known: description, frames, model, parameters, seed, "
                 "zip)"),
    ({"seed": -1}, "s.toml: seed: must be a non-negative integer, not -1"),
    ({"seed": 1.5}, "s.toml: seed: must be a non-negative integer, not 1.5"),
    ({"parameters": {"aggressors": []}}, "s.toml: parameters.aggressors: an empty list gives "
                                         "no points"),
    ({"parameters": {"aggressors": [1, 2, 1]}}, "s.toml: parameters.aggressors: 1 is listed "
                                                "twice"),
    ({"parameters": {"aggressors": [[1]]}}, "s.toml: parameters.aggressors: values must be "
                                            "numbers, strings or booleans, not list"),
    ({"parameters": {"aggressors": {"a": 1}}}, "s.toml: parameters.aggressors: must be a value "
                                               "or a list, not a table"),
    ({"parameters": {"aggressors": float("nan")}}, "s.toml: parameters.aggressors: nan is not "
                                                   "a finite number"),
    ({"parameters": {"aggresors": 2}}, "s.toml: parameters.aggresors: unknown parameter of "
                                       "sweep_points:evaluate (known: aggressor_power_db, "
                                       "aggressors, frames, scheme, sleep_s, t_int_s)"),
    ({"frames": 10, "parameters": {"frames": 20}}, "s.toml: frames: given both at the top and "
                                                   "in [parameters]"),
    ({"zip": {"g": {"aggressors": [1, 2], "scheme": ["off"]}}}, "s.toml: zip.g: lists of "
                                                                "different lengths ([1, 2])"),
    ({"parameters": {"scheme": "off"}, "zip": {"g": {"scheme": ["off"]}}},
     "s.toml: zip.g.scheme: parameter given twice"),
    ({"zip": {"g": {"scheme": ["off", "off"]}}}, "s.toml: zip.g: a combination is listed twice"),
    ({"model": "sweep_points"}, "s.toml: model: model 'sweep_points' is not of the form "
                                "'package.module:function'"),
    ({"model": "sweep_points:nothing"}, "s.toml: model: model 'sweep_points:nothing': "
                                        "sweep_points has no function nothing"),
])
def test_bad_specs_are_refused_naming_file_and_key(data, message):
    data = {"model": MODEL, **data}
    with pytest.raises(SpecError) as caught:
        parse(data, "s.toml")
    assert str(caught.value) == message


def test_unreadable_spec_files_are_refused(tmp_path):
    with pytest.raises(SpecError, match=r"^.*nothing\.toml: cannot read \(No such file"):
        load(tmp_path / "nothing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("seed = = 1\n")
    with pytest.raises(SpecError, match=r"bad\.toml: not valid TOML \(.*line 1"):
        load(bad)


def test_keys_and_seeds_depend_on_parameters_not_on_order():
    a = {"scheme": "off", "aggressors": 2}
    b = {"aggressors": 2, "scheme": "off"}
    assert point_key(MODEL, 1, a) == point_key(MODEL, 1, b)
    assert point_seed(1, a).generate_state(4).tolist() == \
        point_seed(1, b).generate_state(4).tolist()
    # A different value, type, seed or model is a different point
    for other in (point_key(MODEL, 1, {**a, "aggressors": 3}),
                  point_key(MODEL, 1, {**a, "aggressors": 2.0}),
                  point_key(MODEL, 2, a), point_key("other:evaluate", 1, a)):
        assert other != point_key(MODEL, 1, a)
    assert point_seed(1, a).generate_state(4).tolist() != \
        point_seed(2, a).generate_state(4).tolist()


# Engine ----------------------------------------------------------------------------------------

def test_results_are_the_same_with_one_and_two_workers(client, tmp_path):
    spec = grid(scheme=["off", "mseq", "masked"], aggressors=[1, 2, 4, 8], frames=200)
    outcome = run_sweep(spec, tmp_path / "two", client)
    assert (outcome.computed, outcome.reused, outcome.interrupted) == (12, 0, False)
    with cluster(1, processes=False) as single:
        run_sweep(spec, tmp_path / "one", single)
    two, one = table(tmp_path / "two" / "results.parquet"), \
        table(tmp_path / "one" / "results.parquet")
    assert two == one
    # Every row is the model evaluated on its own with the point's seed
    for row, point in zip(two, spec.points()):
        expected = sweep_points.evaluate(point, point_seed(11, point))
        assert row["first_draw"] == expected["first_draw"]
        assert row["wrong_depth"] == expected["wrong_depth"]
        assert (row["scheme"], row["aggressors"]) == (point["scheme"], point["aggressors"])
    assert len({row["first_draw"] for row in two}) == 12      # a stream of its own per point


def test_a_second_run_computes_nothing_and_an_added_point_only_itself(client, tmp_path):
    first = run_sweep(grid(aggressors=[1, 2]), tmp_path, client)
    assert (first.computed, first.reused) == (2, 0)
    again = run_sweep(grid(aggressors=[1, 2]), tmp_path, client)
    assert (again.computed, again.reused) == (0, 2)
    before = table(tmp_path / "results.parquet")
    grown = run_sweep(grid(aggressors=[1, 2, 3]), tmp_path, client)
    assert (grown.computed, grown.reused, grown.total) == (1, 2, 3)
    after = table(tmp_path / "results.parquet")
    assert after[:2] == before and after[2]["aggressors"] == 3


def test_a_point_added_to_a_spec_leaves_the_others_unchanged(client, tmp_path):
    run_sweep(grid(aggressors=[2, 4]), tmp_path / "a", client)
    run_sweep(grid(aggressors=[1, 2, 3, 4]), tmp_path / "b", client)
    a = {row["aggressors"]: row for row in table(tmp_path / "a" / "results.parquet")}
    b = {row["aggressors"]: row for row in table(tmp_path / "b" / "results.parquet")}
    assert a[2] == b[2] and a[4] == b[4]


def test_an_interruption_keeps_the_finished_points(client, tmp_path):
    spec = grid(aggressors=list(range(1, 9)), sleep_s=0.05)
    seen = []

    def progress(done, total, computed, elapsed_s):
        seen.append((done, total, computed))
        if computed == 3:
            raise KeyboardInterrupt

    outcome = run_sweep(spec, tmp_path, client, progress=progress)
    assert outcome.interrupted and outcome.computed == 3 and outcome.missing == 5
    assert seen == [(0, 8, 0), (1, 8, 1), (2, 8, 2), (3, 8, 3)]
    assert len(os.listdir(tmp_path / "points")) == 3
    assert len(table(tmp_path / "results.parquet")) == 3
    rest = run_sweep(spec, tmp_path, client)
    assert (rest.computed, rest.reused, rest.interrupted) == (5, 3, False)


def test_a_point_function_is_injected(client, tmp_path):
    def model(point, seed):
        return {"double": 2 * point["aggressors"], "state": int(seed.generate_state(1)[0])}

    outcome = run_sweep(grid(aggressors=[1, 5]), tmp_path, client, function=model)
    rows = table(outcome.table)
    assert [row["double"] for row in rows] == [2, 10]
    assert rows[0]["state"] == int(point_seed(11, grid(aggressors=1).points()[0])
                                   .generate_state(1)[0])


def test_a_point_the_model_checks_is_refused_before_any_work():
    with pytest.raises(SpecError) as caught:
        grid(frames=[10, 0], aggressors=2)
    assert str(caught.value) == 'grid.toml: point {"aggressors":2,"frames":0}: frames must be ' \
                                'at least 1, not 0'


def test_a_refused_point_stops_the_sweep_with_one_line(client, tmp_path):
    spec = parse({"model": MODEL, "seed": 11, "parameters": {"frames": [10, 0]}}, "grid.toml",
                 defaults=sweep_points.PARAMETERS)  # given defaults: no check beforehand
    with pytest.raises(SweepError) as caught:
        run_sweep(spec, tmp_path, client)
    assert str(caught.value).startswith('point {"aggressor_power_db":0.0,"aggressors":1,'
                                        '"frames":0,')
    assert str(caught.value).endswith(": frames must be at least 1, not 0")


def test_a_model_that_fails_stops_the_sweep_with_one_line(client, tmp_path, capsys):
    # Any exception of the model, not only a refusal: it had ended in a traceback from the worker
    with pytest.raises(SweepError) as caught:
        run_sweep(grid(aggressors=[1]), tmp_path, client, function=lambda point, seed: 1 / 0)
    assert str(caught.value).startswith('point {"aggressor_power_db":0.0,"aggressors":1,')
    assert str(caught.value).endswith(": the model failed: ZeroDivisionError: division by zero")
    # A spec naming a function that is no model (math.sqrt takes one argument, not two)
    spec = tmp_path / "sqrt.toml"
    spec.write_text('model = "math:sqrt"\n')
    status = main(["sweep", str(spec), "-o", str(tmp_path / "out"), "--threads"])
    err = capsys.readouterr().err
    assert status == 1 and "Traceback" not in err
    assert err.splitlines()[-1].startswith("fliss: error: point ")
    assert err.splitlines()[-1].endswith("the model failed: TypeError: math.sqrt() takes "
                                         "exactly one argument (2 given)")


@pytest.mark.parametrize("result, message", [
    ([1, 2], "the model returned list, not a dict of metrics"),
    ({"curve": [1, 2]}, "metric 'curve' is list, not a number, string, boolean or None"),
])
def test_results_that_are_not_flat_rows_are_refused(client, tmp_path, result, message):
    with pytest.raises(SweepError, match=re.escape(message)):
        run_sweep(grid(), tmp_path, client, function=lambda point, seed: result)


def test_a_damaged_stored_point_is_named(client, tmp_path):
    spec = grid()
    run_sweep(spec, tmp_path, client)
    (path,) = (tmp_path / "points").iterdir()
    path.write_text("{")
    with pytest.raises(SweepError, match=re.escape(f"{path}: cannot read a finished point")):
        run_sweep(spec, tmp_path, client)


def test_compute_hands_over_every_result(client):
    got = {}
    assert compute(client, {k: (pow, (k, 2)) for k in range(6)},
                   lambda key, result, elapsed_s: got.update({key: result}))
    assert got == {k: k * k for k in range(6)}


def test_table_merges_a_metric_equal_to_a_parameter(tmp_path):
    spec = grid(frames=[5, 6])
    store = Store(tmp_path)
    for point in spec.points():
        store.save(point_key(spec.model, spec.seed, point),
                   {"point": point, "result": {"frames": point["frames"], "x": 1}})
    rows = table_rows(spec, store)
    assert [(row["frames"], row["x"]) for row in rows] == [(5, 1), (6, 1)]
    assert "frames_result" not in rows[0]
    write_table([{"a": 1, "b": "x"}, {"a": 2.5, "b": None}], tmp_path / "t.parquet")
    assert table(tmp_path / "t.parquet") == [{"a": 1.0, "b": "x"}, {"a": 2.5, "b": None}]


# The command -----------------------------------------------------------------------------------

def write_spec(path, **extra):
    lines = [f'model = "{MODEL}"', "seed = 2", "frames = 50", "[parameters]",
             'scheme = ["off", "mseq"]', "aggressors = [1, 2, 4]",
             "aggressor_power_db = [0.0, 6.0]", "t_int_s = [0.01, 0.03]"]
    lines += [f"{key} = {value}" for key, value in extra.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_sweep_command_end_to_end(tmp_path, capsys):
    spec = write_spec(tmp_path / "s.toml")
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "-o", str(out), "--workers", "2", "--threads"]) == 0
    captured = capsys.readouterr()
    assert "24 points computed" in captured.err
    assert re.search(r"^\[24/24 points\] [0-9.]+ points/s, ETA 0:00$", captured.err, re.MULTILINE)
    rows = table(out / "results.parquet")
    assert len(rows) == 24 and rows[0]["s_db"] == 30.0 and rows[2]["s_db"] == 24.0
    for name in ("p_wrong_depth_vs_aggressors.png", "detection_curves.png",
                 "s_vs_aggressor_power.png"):
        assert (out / name).stat().st_size > 1000
        assert f"figure: {out / name}" in captured.out
    assert main(["sweep", str(spec), "-o", str(out), "--threads"]) == 0
    assert "0 points computed" in capsys.readouterr().err


@pytest.mark.parametrize("typo, argv, message", [
    (None, ["--workers", "0"], "--workers must be at least 1, not 0"),
    ("agressors", [], "{spec}: parameters.agressors: unknown parameter of sweep_points:evaluate"),
])
def test_sweep_command_refuses_with_one_line(tmp_path, capsys, typo, argv, message):
    spec = write_spec(tmp_path / "s.toml")
    if typo:
        spec.write_text(spec.read_text().replace("aggressors =", f"{typo} ="))
    assert main(["sweep", str(spec), "-o", str(tmp_path / "out")] + argv) == 1
    line = capsys.readouterr().err.strip().splitlines()[-1]
    assert line.startswith("fliss: error: " + message.format(spec=spec))
    assert not (tmp_path / "out" / "points").exists()


def test_an_unreachable_scheduler_is_one_line():
    with pytest.raises(SweepError, match=r"^cannot reach the Dask scheduler at "
                                         r"tcp://127\.0\.0\.1:9: "):
        with cluster(scheduler="tcp://127.0.0.1:9", timeout_s=1):
            pass


def left_in_group(group):
    """Live (not zombie) processes of a process group."""
    alive = []
    for process in psutil.process_iter(["pid", "status"]):
        try:
            if os.getpgid(process.pid) == group and process.status() != psutil.STATUS_ZOMBIE:
                alive.append(process.pid)
        except (ProcessLookupError, psutil.Error):
            pass
    return alive


def _sigint_as_at_a_terminal():
    # A command started in the foreground of a terminal has SIGINT at its default; a test run
    # from a background job (`cmd &`, `nohup`) would pass it on ignored, and Python then never
    # raises KeyboardInterrupt
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("whom, signum", [("group", signal.SIGINT), ("main", signal.SIGTERM)])
def test_ctrl_c_stops_the_workers_and_keeps_the_finished_points(tmp_path, whom, signum):
    """Ctrl-C at a terminal signals the whole process group; kill signals the command only."""
    spec = write_spec(tmp_path / "s.toml", sleep_s=0.4)
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([TESTS, os.environ.get("PYTHONPATH", "")]))
    process = subprocess.Popen([sys.executable, "-m", "fliss", "sweep", str(spec), "-o",
                                str(out), "--workers", "2"], env=env, start_new_session=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               preexec_fn=_sigint_as_at_a_terminal)
    try:
        deadline = time.monotonic() + 60
        while not (out / "points").is_dir() or not os.listdir(out / "points"):
            assert process.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        if whom == "group":
            os.killpg(process.pid, signum)
        else:
            process.send_signal(signum)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    match = re.fullmatch(r"fliss: interrupted; (\d+) of 24 points finished and kept in .*; run "
                         r"the same command again to compute the other (\d+)", last)
    assert match, last
    finished = int(match.group(1))
    assert 1 <= finished < 24 and int(match.group(2)) == 24 - finished
    assert len([n for n in os.listdir(out / "points") if n.endswith(".json")]) == finished
    assert len(table(out / "results.parquet")) == finished
    deadline = time.monotonic() + 10
    while left_in_group(process.pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert left_in_group(process.pid) == []


# With the interference model ------------------------------------------------------------------

def test_the_example_spec_is_valid_for_the_interference_model():
    pytest.importorskip("fliss.sim.studies.interference")
    spec = load(os.path.join(ROOT, "examples", "sweep-quick.toml"))
    assert spec.model == "fliss.sim.studies.interference:evaluate"
    assert len(spec.points()) == 3 * 4 * 3
    assert set(spec.varied()) == {"scheme", "aggressors", "aggressor_power"}


def test_a_tiny_interference_sweep_through_the_command(tmp_path, capsys):
    pytest.importorskip("fliss.sim.studies.interference")
    spec = tmp_path / "tiny.toml"
    spec.write_text('seed = 1\nframes = 2\n[parameters]\nscheme = ["off", "masked"]\n'
                    'aggressors = [1, 2]\nframes_per_run = 2\n')
    assert main(["-q", "sweep", str(spec), "-o", str(tmp_path / "out"), "--threads"]) == 0
    rows = table(tmp_path / "out" / "results.parquet")
    assert [(row["scheme"], row["aggressors"]) for row in rows] == \
        [("off", 1), ("off", 2), ("masked", 1), ("masked", 2)]
    for row in rows:
        assert row["frames"] == 2 and 0.0 <= row["p_wrong_depth"] <= 1.0
        assert row["p_wrong_depth_lo"] <= row["p_wrong_depth"] <= row["p_wrong_depth_hi"]
    assert (tmp_path / "out" / "p_wrong_depth_vs_aggressors.png").exists()


def test_sweep_command_on_an_existing_scheduler(client, tmp_path, capsys):
    spec = write_spec(tmp_path / "s.toml")
    address = client.scheduler.address
    assert main(["sweep", str(spec), "-o", str(tmp_path / "out"), "--scheduler", address,
                 "--no-figures"]) == 0
    assert f"24 points of {spec} on {address}" in capsys.readouterr().err
    assert len(table(tmp_path / "out" / "results.parquet")) == 24
    assert client.status == "running"         # the command closed its client, not the cluster


def test_the_spec_in_the_docs_gives_the_points_it_says(tmp_path):
    pytest.importorskip("fliss.sim.studies.interference")
    text = open(os.path.join(ROOT, "docs", "sweeps.md")).read()
    block = text.split("```toml\n", 1)[1].split("```", 1)[0]
    (tmp_path / "doc.toml").write_text(block)
    spec = load(tmp_path / "doc.toml")
    assert len(spec.points()) == 72 and "3 × 4 × 3 × 2 = 72" in text
    assert {(p["length"], p["mask_width"]) for p in spec.points()} == {(3, 3), (6, 6)}


def test_a_sweep_with_the_keyed_victim_and_the_predicting_aggressor(tmp_path, capsys):
    pytest.importorskip("fliss.sim.studies.interference")
    spec = tmp_path / "attack.toml"
    spec.write_text('seed = 1\nframes = 2\n[parameters]\nscheme = ["mseq", "keyed"]\n'
                    'aggressor_kind = ["locked", "predicting"]\nt_int_s = 0.002\n')
    assert main(["-q", "sweep", str(spec), "-o", str(tmp_path / "out"), "--threads",
                 "--no-figures"]) == 0
    rows = table(tmp_path / "out" / "results.parquet")
    assert [(row["scheme"], row["aggressor_kind"], row["attack_locked_runs"]) for row in rows] \
        == [("mseq", "locked", None), ("mseq", "predicting", 2), ("keyed", "locked", None),
            ("keyed", "predicting", 0)]
    assert rows[1]["ghost"] == 2 and rows[1]["ghost_m"] == 10.0


def test_compute_stops_when_a_stop_was_asked_even_if_its_exception_was_swallowed(client):
    # kill during a sweep: the signal's KeyboardInterrupt may be raised inside Dask's own hooks
    # and lost there; the flag the handler also sets stops the loop at the next result.
    from fliss.host import interrupts
    got = []

    def on_result(key, result, elapsed_s):
        got.append(key)
        if len(got) == 2:
            interrupts.requested.set()      # as the handler does, its exception lost

    try:
        assert compute(client, {k: (pow, (k, 2)) for k in range(50)}, on_result) is False
    finally:
        interrupts.requested.clear()
    assert len(got) == 2
