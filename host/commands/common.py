"""What several commands share: progress lines, signals, capture files read with one warning,
times and frequencies from the command line."""

import contextlib
import signal
import sys
import time

from ..errors import UserError
from ..formats import read_file
from ..units import parse_frequency, parse_time
from ...hdl.clock import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles


__all__ = ["Progress", "progress_bar", "sigterm_interrupts", "read_capture_file", "parse_times",
           "add_timing_options", "timing_from_args"]


class Progress:
    """Progress of a capture on a stream (stderr).

    On a terminal, a one-line bar redrawn in place at most ten times a second. Anywhere else (a
    file, a pipe) a plain line at most every ``interval_s`` seconds and one at the end, so
    that a log holds a few lines rather than hundreds of carriage-return updates.
    """

    def __init__(self, total, unit, *, stream=None, enabled=True, width=24, interactive=None,
                 interval_s=10.0):
        self.total, self.unit = total, unit
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        self.width = width
        if interactive is None:
            isatty = getattr(self.stream, "isatty", None)
            interactive = bool(isatty and isatty())
        self.interactive = interactive
        self.interval_s = interval_s if not interactive else 0.1
        self._drawn = time.monotonic() if not interactive else 0.0
        self._length = 0
        self._last = None
        self._extra = ""

    def update(self, done, extra="", force=False):
        if not self.enabled:
            return
        self._extra = extra or self._extra
        now = time.monotonic()
        if not force and now - self._drawn < self.interval_s:
            return
        self._drawn = now
        shown = f"{done:.1f}/{self.total:g}" if isinstance(done, float) else \
            f"{done}/{self.total}"
        if not self.interactive:
            line = f"[{shown} {self.unit}] {self._extra}".rstrip()
            if line != self._last:
                self._write(line + "\n")
                self._last = line
            return
        fraction = min(max(done / self.total, 0.0), 1.0) if self.total else 0.0
        filled = int(round(fraction * self.width))
        line = f"[{'#' * filled}{'.' * (self.width - filled)}] {shown} {self.unit} {extra}"
        pad = max(self._length - len(line), 0)
        self._write("\r" + line + " " * pad)
        self._length = len(line)

    def _write(self, text):
        try:
            self.stream.write(text)
            self.stream.flush()
        except OSError:     # the terminal is gone (a hangup): the capture goes on
            self.enabled = False

    def close(self):
        if self.enabled and self.interactive and self._length:
            self._write("\n")


def _duration(seconds):
    seconds = int(round(seconds))
    if seconds >= 3600:
        return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m"
    return f"{seconds // 60}:{seconds % 60:02d}"


def progress_bar(stream=None, enabled=True):
    """A progress callback for :func:`~fliss.host.sweep.engine.run_sweep`: points done of the
    total, points per second of this run, and the time left. Returns ``(callback, bar)``."""
    state = {}

    def update(done, total, computed, elapsed_s):
        bar = state.get("bar")
        if bar is None:
            bar = state["bar"] = Progress(total, "points", stream=stream, enabled=enabled)
        extra = "finished already" if done == total else "starting"
        if computed and elapsed_s > 0:
            rate = computed / elapsed_s
            extra = f"{rate:.3g} points/s, ETA {_duration((total - done) / rate)}"
        bar.update(done, extra, force=done in (0, total) or not computed)

    def close():
        if "bar" in state:
            state["bar"].close()

    return update, close


@contextlib.contextmanager
def sigterm_interrupts():
    """SIGTERM raises :exc:`KeyboardInterrupt` in the main thread, as Ctrl-C does; both also
    set :data:`fliss.host.interrupts.requested`, for loops where the exception may be swallowed
    by a library's own code."""
    from .. import interrupts

    def handler(signum, frame):
        interrupts.requested.set()
        raise KeyboardInterrupt

    interrupts.requested.clear()
    try:
        # (a SIGINT ignored, as in a background job of a shell, stays ignored)
        previous = {number: signal.signal(number, handler)
                    for number in (signal.SIGTERM, signal.SIGINT)
                    if signal.getsignal(number) is not signal.SIG_IGN}
    except ValueError:                      # not the main thread
        yield
        return
    try:
        yield
    finally:
        for number, action in previous.items():
            signal.signal(number, action)
        interrupts.requested.clear()        # (a stop asked for is this command's only)


def read_capture_file(path):
    """The capture in ``path`` (a FLISS capture, a PTU or a Photon-HDF5 file); one warning
    line (stderr) for what of it could not be read."""
    try:
        capture = read_file(path)
    except ValueError as error:
        raise UserError(str(error)) from None
    if capture.problems:
        print(f"fliss: warning: {path}: {'; '.join(capture.problems)}", file=sys.stderr)
    return capture


def parse_times(texts, flag):
    try:
        return [parse_time(text) for text in texts]
    except ValueError as error:
        raise UserError(f"{flag}: {error}") from None


def _parse_frequency(text, flag):
    try:
        return parse_frequency(text)
    except ValueError as error:
        raise UserError(f"{flag} {text}: {error}") from None


def timing_from_args(args):
    clock_hz = _parse_frequency(args.clock, "--clock")
    prf_hz = _parse_frequency(args.prf, "--prf")
    try:
        return clock_hz, period_cycles(clock_hz, prf_hz)
    except ValueError as error:
        raise UserError(str(error)) from None


def add_timing_options(parser):
    parser.add_argument("--clock", default=f"{DEFAULT_CLOCK_HZ // 1_000_000}MHz", metavar="HZ",
                        help="system clock frequency (80MHz, 79.5MHz, ...)")
    parser.add_argument("--prf", default=f"{DEFAULT_PRF_HZ // 1_000_000}MHz", metavar="HZ",
                        help="nominal pulse repetition frequency")
