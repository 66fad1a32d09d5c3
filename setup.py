"""Which files the ``fliss`` distribution holds: every package and every data file of the
repository's source trees, found by walking them (no list kept by hand).

The repository keeps one top-level folder per subpackage (``hdl/`` is ``fliss.hdl``, ...): the
layout the README describes. :data:`TREES` maps each folder to its package; every folder below
it that holds an ``__init__.py`` is a package, and every other file in a package's folder
(``harness.cpp``, templates, Verilog declarations, ...) is its data. Caches and editor leftovers
(:data:`LEFT_OUT`) are not. The metadata is in ``pyproject.toml``; ``tests/project/test_wheel.py``
checks the wheel against ``git ls-files`` and builds it again from the sdist.
"""

import os
from pathlib import Path

from setuptools import setup


ROOT = Path(__file__).resolve().parent

#: Each top-level folder of the repository and the package it is.
TREES = {
    "fliss": "fliss",
    "fliss.hdl": "hdl",
    "fliss.protocol": "protocol",
    "fliss.analysis": "analysis",
    "fliss.sim": "sim",
    "fliss.host": "host",
    "fliss.boards": "boards",
    "fliss.formal": "formal",
}

#: Names that are never part of the distribution: byte code, caches, editors' files.
LEFT_OUT_DIRS = {"__pycache__", ".pytest_cache", ".mypy_cache", ".ruff_cache"}
LEFT_OUT_SUFFIXES = (".pyc", ".pyo", ".swp", "~")


def _left_out(name):
    return name.startswith(".") or name.endswith(LEFT_OUT_SUFFIXES)


def layout(root=ROOT):
    """``(packages, package_dir, package_data)`` of the trees under ``root``."""
    packages, package_dir, package_data = [], {}, {}
    for package, folder in TREES.items():
        for path, dirs, files in os.walk(root / folder):
            dirs[:] = sorted(d for d in dirs if d not in LEFT_OUT_DIRS and not d.startswith("."))
            here = Path(path)
            if "__init__.py" not in files:
                dirs.clear()        # not a package: nor is anything below it
                continue
            relative = here.relative_to(root / folder)
            name = ".".join([package, *relative.parts])
            packages.append(name)
            package_dir[name] = here.relative_to(root).as_posix()
            data = sorted(f for f in files if not f.endswith(".py") and not _left_out(f))
            # A data folder inside a package (no __init__.py of its own): all of its files.
            for sub in dirs:
                if not (here / sub / "__init__.py").exists():
                    for sub_path, sub_dirs, sub_files in os.walk(here / sub):
                        sub_dirs[:] = sorted(d for d in sub_dirs
                                             if d not in LEFT_OUT_DIRS and not d.startswith("."))
                        data += sorted(
                            (Path(sub_path) / f).relative_to(here).as_posix()
                            for f in sub_files if not _left_out(f))
            if data:
                package_data[name] = data
    return packages, package_dir, package_data


if __name__ == "__main__":
    packages, package_dir, package_data = layout()
    setup(packages=packages, package_dir=package_dir, package_data=package_data)
