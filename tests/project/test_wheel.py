"""The distribution as pip builds it: the wheel holds every file of the source trees that git
tracks, and nothing else; the sdist builds the same wheel.

What the installed wheel does (every command, the demo, a capture on a virtual board) is run
by ``.ci/installed.py`` in a fresh environment outside the checkout (``make test-installed``).
"""

import hashlib
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest


ROOT = Path(__file__).resolve().parents[2]

#: The repository's folders and where their files go in the wheel (the README's folder map).
FOLDERS = {"fliss": "fliss", "hdl": "fliss/hdl", "protocol": "fliss/protocol",
           "analysis": "fliss/analysis", "sim": "fliss/sim", "host": "fliss/host",
           "boards": "fliss/boards", "formal": "fliss/formal"}


def _tracked():
    """The files git knows in the package folders, as the wheel should name them."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard",
                             "--", *FOLDERS], cwd=ROOT,
                            capture_output=True, check=True).stdout.decode().split("\0")
    names = set()
    for name in filter(None, listed):
        if not (ROOT / name).is_file():
            continue            # deleted in the working tree, not yet in git
        folder, _, rest = name.partition("/")
        names.add(f"{FOLDERS[folder]}/{rest}")
    return names


def _build(what, source, output):
    done = subprocess.run([sys.executable, "-m", "build", f"--{what}", "--outdir", str(output),
                           str(source)], capture_output=True, text=True)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    built = sorted(output.glob("*.whl" if what == "wheel" else "*.tar.gz"))
    assert len(built) == 1, built
    return built[0]


def _contents(wheel):
    """``{name: sha256}`` of a wheel's files, its RECORD aside (it lists the others' hashes)."""
    with zipfile.ZipFile(wheel) as archive:
        return {info.filename: hashlib.sha256(archive.read(info)).hexdigest()
                for info in archive.infolist()
                if not info.filename.endswith(".dist-info/RECORD")}


def _copy_of_the_tree(folder):
    """The files git knows in the working tree (tracked, or new and not ignored), copied as a
    fresh clone would hold them: no build/ of an earlier build, no egg-info, no caches."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
                            cwd=ROOT, capture_output=True, check=True).stdout.decode()
    for name in filter(None, listed.split("\0")):
        source = ROOT / name
        if source.is_file():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, folder / name)
    return folder


@pytest.fixture(scope="module")
def dist(tmp_path_factory):
    if subprocess.run([sys.executable, "-c", "import build"]).returncode:
        pytest.skip("the `build` package is not installed (pip install -e '.[test]')")
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout: the tracked files are unknown")
    folder = tmp_path_factory.mktemp("dist")
    tree = _copy_of_the_tree(folder / "tree")
    sdist = _build("sdist", tree, folder / "sdist")
    wheel = _build("wheel", tree, folder / "wheel")
    return sdist, wheel, folder


def test_wheel_holds_every_tracked_file_and_nothing_else(dist):
    _, wheel, _ = dist
    files = {name for name in _contents(wheel) if ".dist-info/" not in name}
    tracked = _tracked()
    assert sorted(tracked - files) == []            # missed: a module, harness.cpp, a template
    assert sorted(files - tracked) == []            # left over: caches, build products
    # Data files are there, not only modules (the fast board's C++ harness among them).
    assert "fliss/sim/boards/harness/harness.cpp" in files


def test_wheel_metadata_names_the_version_and_the_command(dist):
    _, wheel, _ = dist
    version = __import__("fliss").__version__
    assert wheel.name == f"fliss-{version}-py3-none-any.whl"
    with zipfile.ZipFile(wheel) as archive:
        metadata = archive.read(f"fliss-{version}.dist-info/METADATA").decode()
        entry_points = archive.read(f"fliss-{version}.dist-info/entry_points.txt").decode()
        names = archive.namelist()
    assert f"\nVersion: {version}\n" in metadata
    assert "fliss = fliss.host.cli:main" in entry_points
    assert f"fliss-{version}.dist-info/licenses/LICENSE" in names


def test_sdist_builds_the_same_wheel(dist):
    sdist, wheel, folder = dist
    with tarfile.open(sdist) as archive:
        archive.extractall(folder / "unpacked", filter="data")
    unpacked = next((folder / "unpacked").iterdir())
    again = _build("wheel", unpacked, folder / "again")
    assert again.name == wheel.name
    first, second = _contents(wheel), _contents(again)
    assert sorted(set(first) ^ set(second)) == []
    assert [name for name in first if first[name] != second[name]] == []
