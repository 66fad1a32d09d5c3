"""The README's Python API examples run as they are and print what the README says; its table
gives the shapes the arrays have."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np

import fliss
from fliss.sim.boards.model import model_board
from fliss.sim.scene import Scene, line_pixels, time_of_flight


README = Path(__file__).resolve().parents[2] / "README.md"


def examples():
    section = README.read_text().split("\n## Python API\n", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"^```python\n(.*?)^```", section, flags=re.MULTILINE | re.DOTALL)
    assert len(blocks) == 2         # the histograms, the imager
    return blocks


def example():
    return examples()[0]


def test_readme_example_runs():
    run = subprocess.run([sys.executable, "-c", example()], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stderr == ""              # the library prints nothing, warns of nothing here
    lines = run.stdout.splitlines()
    assert lines[0] == "10 ms 1 MHz"
    assert lines[1] == "(5, 2048) (2048,)"          # 8192 codes in bins of 2**2
    peak_ns = float(re.fullmatch(r"peak at ([\d.]+) ns", lines[2]).group(1))
    assert abs(peak_ns - time_of_flight(Scene().distance_m) * 1e9) < 0.5
    assert lines[3] == "True ('timestamp', 'address', 'collision', 'pulse')"
    assert len(lines) == 4


def test_readme_imager_example_runs():
    run = subprocess.run([sys.executable, "-c", examples()[1]], capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stderr == ""
    lines = run.stdout.splitlines()
    assert lines[0] == "(2, 64, 128) [ 0 63]"        # 64 pixels, 8192 codes in bins of 2**6
    # the line scene's depths from its definition (wall, object, wall), to the 0.1 m printed
    depths = [float(value) for value in re.findall(r"[\d.]+", lines[1].split("]")[0])]
    line = line_pixels()
    assert np.allclose(depths, line.distance_m[[0, 30, 59]], atol=0.051)
    assert lines[1].endswith("] False")
    assert len(lines) == 2


def table_shapes(call):
    """{array: shape} that the README's API table gives in the row of ``call``: a name (or a
    list of names) right before a shape, ``(n, P)``, applies it."""
    row = re.search(rf"^\| `{re.escape(call)}` \|(.*)\|$", README.read_text(),
                    flags=re.MULTILINE).group(1)
    shapes = {}
    for names, shape in re.findall(r"((?:`\w+`, )*`\w+`)(?: \(\w+\))? `\(([^)]*)\)`", row):
        for name in re.findall(r"`(\w+)`", names):
            shapes[name] = tuple(word.strip() for word in shape.split(",") if word.strip())
    return shapes


def test_api_table_gives_the_shapes_of_the_arrays():
    n, pixels, bin_shift = 2, 4, 3
    with model_board(scene=Scene(pixels=line_pixels(), detections_per_pulse=0.02)) as model:
        with fliss.connect(model.path) as board:
            board.configure(integration="2ms", bin_shift=bin_shift)
            histograms = board.acquire(n)
            board.configure(pixels=pixels, first_pixel=20)
            images = board.acquire_image(n)
            depth = board.acquire_depth(n)
    bins = 8192 >> bin_shift                   # 8192 codes a pixel
    sizes = {"n": n, "P": pixels, "bins": bins, "N": bins}
    for call, result, least in (("board.acquire(n)", histograms, 2),
                                ("board.acquire_image(n)", images, 4),
                                ("board.acquire_depth(n)", depth, 7)):
        shapes = table_shapes(call)
        assert len(shapes) >= least, call
        for name, shape in shapes.items():
            assert np.shape(getattr(result, name)) == tuple(sizes[s] for s in shape), \
                f"{call}: {name}"
