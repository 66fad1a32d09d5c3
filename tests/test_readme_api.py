"""The README's Python API example runs as it is and prints what the README says."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np

from fliss.sim.scene import Scene, line_pixels, time_of_flight


README = Path(__file__).resolve().parent.parent / "README.md"


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
