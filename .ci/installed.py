"""FLISS as a user installs it: the wheel in a fresh virtual environment outside the checkout.

    python .ci/installed.py --wheel DIST/fliss-X-py3-none-any.whl --python python3.13 [--full]
        [--min-deps] [--fresh-cache]

Makes a virtual environment with ``--python`` in a temporary folder, installs the wheel (with its
``virtual`` and ``formats`` extras for ``--full``; with ``--min-deps``, every dependency at the
lower bound ``pyproject.toml`` claims), and runs, from another temporary folder with nothing of the
checkout on ``sys.path``:

* ``fliss --version`` (the checkout's version) and every command's ``--help``;
* ``fliss generate``: the same files as the checkout's ``fliss generate``, byte for byte;
* ``examples/amaranth_delay_core/`` copied out and elaborated to Verilog on the installed
  ``fliss.hdl`` (a user's own Amaranth design around the delay core);
* on the Python model board: a histogram and a raw capture, ``analyze``, ``plot`` and
  (``--full``) ``export`` to PTU and Photon-HDF5, each read back by ``analyze``;
* with ``--full``: ``fliss demo`` (the fast virtual board's harness compiled into the per-user
  cache: a fresh one with ``--fresh-cache``) and ``fliss board`` with a capture, ``analyze`` and
  ``export`` on it; and that nothing was written into site-packages.

Prints a line per check and closes with ``N passed, N failed``; exits 1 when a check failed.
"""

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - CI runs this with the checkout's Python 3.11
    import tomli as tomllib


ROOT = Path(__file__).resolve().parent.parent


def _sigint_default():
    # The board's SIGINT as a terminal's, whatever this script inherited (SIGINT is ignored in
    # a background job, and a child inherits that): stop() interrupts it with SIGINT.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class Checks:
    def __init__(self):
        self.passed, self.failed = 0, 0

    def run(self, what, function):
        started = time.monotonic()
        try:
            detail = function()
        except Exception as error:  # a failed check is reported and the next one runs
            self.failed += 1
            print(f"FAIL {what}: {error}", flush=True)
            return
        self.passed += 1
        extra = f": {detail}" if detail else ""
        print(f"ok   {what} ({time.monotonic() - started:.1f} s){extra}", flush=True)


def run(argv, *, cwd, env, timeout=600, check=True):
    done = subprocess.run([str(a) for a in argv], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)
    if check and done.returncode != 0:
        tail = (done.stderr or done.stdout).strip().splitlines()[-5:]
        raise RuntimeError(f"{' '.join(map(str, argv))} exited {done.returncode}: "
                           + " | ".join(tail))
    return done


def find_python(spec):
    """The interpreter ``spec`` names: a command or path that runs, or a version (``3.10``)
    that pyenv holds (its shims name versions that are not selected)."""
    for candidate in (spec, f"python{spec}"):
        try:
            if subprocess.run([candidate, "-c", "pass"], capture_output=True).returncode == 0:
                return candidate
        except OSError:
            pass
    version = spec.removeprefix("python")
    root = os.environ.get("PYENV_ROOT", str(Path.home() / ".pyenv"))
    found = sorted(Path(root, "versions").glob(f"{version}.*/bin/python"),
                   key=lambda path: [int(part) if part.isdigit() else 0
                                     for part in path.parent.parent.name.split(".")])
    if not found:
        raise SystemExit(f"installed.py: no Python {spec} here (not on PATH, not in {root})")
    return str(found[-1])


def minimum_requirements():
    """The project's dependencies at the lower bounds it claims (``>=X`` becomes ``==X``)."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    pinned = []
    for requirement in project["dependencies"]:
        spec, _, marker = requirement.partition(";")
        lower = re.search(r">=\s*([^,\s]+)", spec)
        if lower is None:
            raise RuntimeError(f"pyproject.toml: {requirement!r} has no lower bound")
        name = re.match(r"[A-Za-z0-9_.\-]+(\[[^\]]*\])?", spec).group(0)
        pinned.append(f"{name}=={lower.group(1)}" + (f"; {marker.strip()}" if marker else ""))
    return pinned


def environment():
    """The user's environment: nothing of the checkout, no PYTHONPATH, no virtual environment
    active; pip's cache as it is (a fresh per-user cache of FLISS's own is ``--fresh-cache``)."""
    pip_cache = run([sys.executable, "-m", "pip", "cache", "dir"], cwd=ROOT,
                    env=dict(os.environ), check=False).stdout.strip()
    env = {key: value for key, value in os.environ.items()
           if not key.startswith(("PYTHON", "VIRTUAL_ENV", "FLISS_"))}
    if pip_cache:
        env["PIP_CACHE_DIR"] = pip_cache
    return env


class Board:
    """``fliss board`` or the Python model board in the background, its output in a log; its pty
    from that output."""

    def __init__(self, argv, *, cwd, env, timeout):
        self.log = Path(cwd) / f"board-{time.monotonic_ns()}.log"
        with open(self.log, "w") as output:
            self.process = subprocess.Popen([str(a) for a in argv], cwd=cwd, env=env,
                                            stdout=output, stderr=subprocess.STDOUT,
                                            start_new_session=True,
                                            preexec_fn=_sigint_default)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            found = re.search(r"(/dev/pts/\d+)", self.log.read_text())
            if found:
                self.port = found.group(1)
                return
            if self.process.poll() is not None:
                break
            time.sleep(0.2)
        self.stop()
        raise RuntimeError(f"the board printed no pty: {self.tail()}")

    def tail(self):
        return " | ".join(self.log.read_text().strip().splitlines()[-6:])

    def stop(self):
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGINT)
            try:
                self.process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()

    def __enter__(self):
        return self

    def __exit__(self, kind, error, traceback):
        self.stop()
        if error is not None:
            raise RuntimeError(f"{error}; the board's output: {self.tail()}") from None


class Installed:
    """The wheel installed in a fresh environment under ``work``, and the checks run on it from
    another folder (``user``): each method returns a detail for its line or raises."""

    def __init__(self, args, work):
        self.args, self.work = args, work
        self.wheel = args.wheel.resolve()
        self.env = environment()
        if args.fresh_cache:
            self.env["XDG_CACHE_HOME"] = str(work / "cache")
        self.venv, self.user = work / "venv", work / "user"
        self.user.mkdir()
        self.bin = self.venv / "bin"
        self.fliss = self.bin / "fliss"
        self.version = re.search(r'^__version__ = "([^"]+)"',
                                 (ROOT / "fliss" / "__init__.py").read_text(),
                                 flags=re.MULTILINE).group(1)
        self.site = None
        self.before = set()

    def run(self, argv, **options):
        options.setdefault("cwd", self.user)
        return run(argv, env=self.env, **options)

    def _files(self):
        return {p for p in (self.site / "fliss").rglob("*") if "__pycache__" not in p.parts}

    def install(self):
        python, work = self.bin / "python", self.work
        self.run([self.args.python, "-m", "venv", self.venv], cwd=work)
        self.run([python, "-m", "pip", "install", "--quiet", "--upgrade", "pip"], cwd=work)
        if self.args.min_deps:
            self.run([python, "-m", "pip", "install", "--quiet", *minimum_requirements()],
                     cwd=work, timeout=1200)
            self.run([python, "-m", "pip", "install", "--quiet", "--no-deps", f"{self.wheel}"],
                     cwd=work)
        else:
            extras = "[virtual,formats]" if self.args.full else ""
            self.run([python, "-m", "pip", "install", "--quiet", f"{self.wheel}{extras}"],
                     cwd=work, timeout=1200)
        self.site = Path(self.run([python, "-c", "import sysconfig; "
                                   "print(sysconfig.get_paths()['purelib'])"]).stdout.strip())
        self.before = self._files()
        version = self.run([python, "-c", "import sys; print(sys.version.split()[0])"]).stdout
        return f"Python {version.strip()}" + (", lowest dependencies" if self.args.min_deps
                                               else "")

    def imported_from_site_packages(self):
        out = self.run([self.bin / "python", "-c", "import sys, fliss, fliss.hdl.top; "
                        "print(fliss.__file__); print(fliss.hdl.top.__file__); "
                        "print('\\n'.join(sys.path))"]).stdout
        if str(ROOT) in out:
            raise RuntimeError(f"the checkout ({ROOT}) is on sys.path or imported")
        if not out.splitlines()[0].startswith(str(self.site)):
            raise RuntimeError(f"fliss imported from {out.splitlines()[0]}")

    def version_line(self):
        out = self.run([self.fliss, "--version"]).stdout.strip()
        if out != f"fliss {self.version}":
            raise RuntimeError(f"fliss --version says {out!r}, not 'fliss {self.version}'")
        return out

    def every_help(self):
        top = self.run([self.fliss, "--help"]).stdout
        commands = re.findall(r"^    ([a-z][a-z-]*)\s", top, flags=re.MULTILINE)
        if len(commands) < 10:
            raise RuntimeError(f"fliss --help lists {len(commands)} commands")
        for command in commands:
            self.run([self.fliss, command, "--help"])
        return f"{len(commands)} commands"

    def same_verilog(self):
        generated = self.user / "generated"
        self.run([self.fliss, "generate", "-o", generated])
        reference = self.args.reference
        if reference is None:
            reference = self.work / "reference"
            run([sys.executable, "-m", "fliss", "generate", "-o", reference], cwd=ROOT,
                env=dict(os.environ))
        files = [p for p in reference.rglob("*") if p.is_file()]
        for path in files:
            other = generated / path.relative_to(reference)
            if not other.is_file() or other.read_bytes() != path.read_bytes():
                raise RuntimeError(f"{path.relative_to(reference)} differs from the checkout's")
        extra = [p for p in generated.rglob("*")
                 if p.is_file() and not (reference / p.relative_to(generated)).exists()]
        if extra:
            raise RuntimeError(f"files only the installed fliss writes: {extra}")
        return f"{len(files)} files equal"

    def model_board_capture(self):
        with Board([self.bin / "python", "-m", "fliss.sim.boards.model"], cwd=self.user,
                   env=self.env, timeout=60) as board:
            self.run([self.fliss, "config", "--port", board.port, "--mode", "masked",
                      "--aggressor", "on"], timeout=60)
            self.run([self.fliss, "capture", "--port", board.port, "--integration", "10ms",
                      "--acquisitions", "2", "-o", "model.h5"], timeout=120)
            self.run([self.fliss, "capture", "--port", board.port, "--readout", "raw",
                      "--duration", "50ms", "-o", "model-raw.h5"], timeout=120)
        self.run([self.fliss, "analyze", "model-raw.h5"])
        out = self.run([self.fliss, "analyze", "model.h5"]).stdout
        self.run([self.fliss, "plot", "model.h5", "-o", "model.png"])
        if not (self.user / "model.png").stat().st_size:
            raise RuntimeError("plot wrote an empty PNG")
        return out.strip().splitlines()[0][:80]

    def amaranth_example(self):
        # examples/ is not in the wheel: a user copies the folder and runs it against the
        # installed fliss.hdl
        folder = self.user / "amaranth_delay_core"
        folder.mkdir()
        for path in (ROOT / "examples" / "amaranth_delay_core").glob("*.py"):
            (folder / path.name).write_bytes(path.read_bytes())
        out = self.run([self.bin / "python", "-c",
                        "import fliss.hdl.delay, ranger_board\n"
                        "from amaranth.back import verilog\n"
                        "text = verilog.convert(ranger_board.RangerOnBoard(48_000_000), "
                        "name='ranger')\n"
                        "print(fliss.hdl.delay.__file__, len(text.splitlines()))"],
                       cwd=folder).stdout.split()
        if "site-packages" not in out[0]:
            raise RuntimeError(f"fliss.hdl.delay came from {out[0]}")
        return f"{out[1]} lines of Verilog"

    def export_model(self):
        # histograms go to PTU (T3 image mode); Photon-HDF5 holds photons: the raw capture's
        for source, target, name in (("model.h5", "ptu", "model.ptu"),
                                     ("model-raw.h5", "ptu", "model-raw.ptu"),
                                     ("model-raw.h5", "photon-hdf5", "model-raw.hdf5")):
            self.run([self.fliss, "export", source, "--to", target, "-o", name])
            if not (self.user / name).stat().st_size:
                raise RuntimeError(f"{name} is empty")
            self.run([self.fliss, "analyze", name])      # read back by fliss too
        return "PTU and Photon-HDF5, read back"

    def demo(self):
        out = self.run([self.fliss, "demo", "--out", "demo"], timeout=1500)
        if not (self.user / "demo" / "demo.png").exists():
            raise RuntimeError("the demo wrote no demo.png")
        return out.stdout.strip().splitlines()[-1][:90]

    def virtual_board_capture(self):
        with Board([self.fliss, "board"], cwd=self.user, env=self.env, timeout=900) as board:
            self.run([self.fliss, "config", "--port", board.port, "--mode", "masked",
                      "--aggressor", "on"], timeout=120)
            self.run([self.fliss, "capture", "--port", board.port, "--integration", "1ms",
                      "--acquisitions", "2", "-o", "virtual.h5"], timeout=300)
        self.run([self.fliss, "analyze", "virtual.h5"])
        self.run([self.fliss, "export", "virtual.h5", "--to", "ptu", "-o", "virtual.ptu"])
        return f"virtual.h5 {(self.user / 'virtual.h5').stat().st_size} bytes"

    def nothing_written_to_site_packages(self):
        after = self._files()
        if after != self.before:
            raise RuntimeError(f"written into site-packages: "
                               f"{sorted(map(str, after - self.before))[:5]}")
        cache = Path(self.env.get("XDG_CACHE_HOME", Path.home() / ".cache"))
        built = list(cache.rglob("*.so")) if cache.exists() else []
        if not built:
            raise RuntimeError(f"no harness library in the per-user cache {cache}")
        return f"harness in {built[0].parent}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--wheel", required=True, type=Path)
    parser.add_argument("--python", default=sys.executable)
    parser.add_argument("--full", action="store_true")
    parser.add_argument("--min-deps", action="store_true")
    parser.add_argument("--fresh-cache", action="store_true")
    parser.add_argument("--reference", type=Path, metavar="DIR",
                        help="the checkout's `fliss generate` output (made here when not given)")
    args = parser.parse_args()
    args.python = find_python(args.python)
    checks = Checks()
    with tempfile.TemporaryDirectory(prefix="fliss-installed-") as temporary:
        smoke = Installed(args, Path(temporary))
        checks.run("install the wheel into a fresh environment", smoke.install)
        if not checks.failed:
            checks.run("imported from site-packages, nothing of the checkout",
                       smoke.imported_from_site_packages)
            checks.run("fliss --version", smoke.version_line)
            checks.run("every command's --help", smoke.every_help)
            checks.run("fliss generate writes the checkout's files", smoke.same_verilog)
            checks.run("model board: config, capture, analyze, plot", smoke.model_board_capture)
            checks.run("the Amaranth example elaborates on the installed fliss.hdl",
                       smoke.amaranth_example)
        if args.full and smoke.site is not None:
            checks.run("export the model board's capture", smoke.export_model)
            checks.run("fliss demo", smoke.demo)
            checks.run("fliss board: config, capture, analyze, export",
                       smoke.virtual_board_capture)
            checks.run("nothing written into site-packages",
                       smoke.nothing_written_to_site_packages)
    print(f"{checks.passed} passed, {checks.failed} failed")
    return 1 if checks.failed else 0


if __name__ == "__main__":
    sys.exit(main())
