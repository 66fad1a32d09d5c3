"""The schemes study's sweep specs (examples/schemes-*.toml) load with every point checked by
its model, and the quick one runs on the sweep engine into a table that docs/schemes_section.py
turns into the docs' section."""

import importlib.util
from pathlib import Path

import pyarrow.parquet as pq

from fliss.host.sweep.engine import cluster, run_sweep
from fliss.host.sweep.spec import load


ROOT = Path(__file__).resolve().parents[2]


def test_the_full_spec_is_the_quick_one_widened():
    quick = load(str(ROOT / "examples" / "schemes-quick.toml"))
    full = load(str(ROOT / "examples" / "schemes-full.toml"))
    assert quick.model == full.model == "fliss.sim.studies.schemes:evaluate"
    # 9 schemes; 2 camera counts at one ambient level, and 7 at three
    assert len(quick.points()) == 9 * 2 and len(full.points()) == 9 * 7 * 3
    schemes = {tuple(sorted(axis[0].items())) for axis in quick.axes if len(axis[0]) > 1}
    assert schemes == {tuple(sorted(axis[0].items())) for axis in full.axes if len(axis[0]) > 1}
    # and the PRF sweep of the coincidence gate: 3 PRFs, without and with FLISS
    assert len(load(str(ROOT / "examples" / "schemes-coincidence-prf.toml")).points()) == 6


def test_the_quick_spec_runs_and_makes_the_docs_section(tmp_path):
    spec = load(str(ROOT / "examples" / "schemes-quick.toml"))
    with cluster(2, processes=False) as client:
        run_sweep(spec, tmp_path, client)
    rows = pq.read_table(tmp_path / "results.parquet").to_pylist()
    assert len(rows) == 18
    # A lone camera at low ambient light finds its echo in every frame, whatever its scheme
    assert all(row["miss"] == 0 for row in rows if row["cameras"] == 1)
    path = ROOT / "docs" / "schemes_section.py"
    module_spec = importlib.util.spec_from_file_location("schemes_section", path)
    section = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(section)
    text = section.section(section.load(tmp_path), "examples/schemes-quick.toml")
    assert text.startswith(section.BEGIN) and text.endswith(section.END)
    assert "| 1e+05 | any: all 9 at 0.000 |" in text
    assert "From `examples/schemes-quick.toml`: 18 points, 10 frames a point" in text
    # a table of fewer points than its spec says so
    assert "18 of its 189 points" in section.section(section.load(tmp_path))
