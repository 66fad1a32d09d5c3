"""Capture from a board into an HDF5 file: the library side of ``fliss capture``.

:func:`capture` sets the acquisition mode and integration time, starts the board, writes what it
sends to a file as it arrives (:class:`~fliss.host.fileformat.CaptureWriter`) and returns a
:class:`CaptureResult`; it prints nothing (the command, :mod:`fliss.host.commands.capture`, reports).
"""

import math
import signal
import time
from dataclasses import dataclass
from typing import Optional

from ..hdl.registers import BY_NAME, TdcSource
from .calibration import read_table
from .client import BoardClient
from .errors import BoardLost, BoardReset, PathError, SettingsError
from .fileformat import CaptureWriter
from .keyed import refuse_used_up
from .kinds import KINDS, kind_of, mode_of
from .rows import FrameRows
from .stream import EventBatch
from .units import format_time


__all__ = ["HEARTBEAT_S", "DATA_TIMEOUT_S", "CaptureResult", "capture", "rate", "check_reset",
           "left_running"]


#: Seconds between STATUS requests during a capture (a heartbeat that finds a silent board).
HEARTBEAT_S = 1.0

#: Seconds without a data packet after which a histogram capture gives the board up (at least;
#: ten integration times if longer), even if it answers commands.
DATA_TIMEOUT_S = 30.0


@dataclass
class CaptureResult:
    """What :func:`capture` did.

    ``reason`` is ``"completed"``, ``"interrupted: SIGINT"`` (or ``SIGTERM``, ``SIGHUP``: the
    signal that stopped it; ``"interrupted"`` alone when not known) or why the board was lost (``lost``, the
    :exc:`~fliss.host.errors.BoardLost`, a :exc:`~fliss.host.errors.BoardReset` for a board
    that was reset); ``complete`` is True when everything asked for was captured.
    ``histograms`` counts the rows saved, ``lost_histograms`` those of them that never arrived
    (rows of zeros marked incomplete). ``link`` and ``stream`` are the client's counters, ``status_start`` and
    ``status_end`` the board's (``status_end`` is None when the board was lost).
    """
    path: str
    mode: str
    histograms: int
    lost_histograms: int
    events: int
    batches: int
    reason: str
    complete: bool
    lost: Optional[BoardLost]
    link: dict
    stream: dict
    status_start: dict
    status_end: Optional[dict]
    #: Depth captures: pixels detected in all the frames saved, the highest peak (counts above
    #: background) and the threshold of the last frame (None before a frame arrives).
    detections: int = 0
    highest: int = 0
    threshold: Optional[int] = None

    @property
    def interrupted(self) -> bool:
        return self.reason.startswith("interrupted")

    @property
    def signal(self) -> Optional[signal.Signals]:
        """The signal that interrupted the capture (None if none, or not known)."""
        name = self.reason.partition(": ")[2] if self.interrupted else ""
        return getattr(signal.Signals, name, None) if name.startswith("SIG") else None

    @property
    def what(self) -> str:
        """What was saved, as text: ``"10 histograms"``, ``"1234 events in 40 packets"``."""
        kind = KINDS[self.mode]
        if kind.framed:
            return f"{self.histograms} {kind.rows}"
        return f"{self.events} events in {self.batches} packets"

    @property
    def board_deliberate(self) -> dict:
        """Events the board dropped as its settings asked, by counter: ``dropped_collision``
        (``--collisions drop``), ``dropped_pixel`` (addresses outside the frame's pixels);
        counters the board does not report are left out."""
        if self.status_end is None:
            return {}
        return {name: self.status_end[name] - self.status_start.get(name, 0)
                for name in ("dropped_collision", "dropped_pixel") if name in self.status_end}

    @property
    def board_dropped(self) -> int:
        """Events the board dropped during the capture (0 when the board was lost)."""
        if self.status_end is None:
            return 0
        return sum(self.status_end[name] - self.status_start.get(name, 0) for name in
                   ("dropped_fifo", "dropped_overrun", "dropped_histogram"))


class _NoProgress:
    def update(self, done, extra="", force=False):
        pass

    def close(self):
        pass


class _Interrupt:
    """Ctrl-C (SIGINT), ``kill`` (SIGTERM) or a closed terminal (SIGHUP) during a capture only
    sets a flag, checked between packets, so that it never breaks into the middle of an HDF5
    write (h5py holds a lock then) or of a packet's decoding, and the board is stopped and the
    file closed. A second one interrupts at once."""

    SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP")
                    if hasattr(signal, name))

    def __init__(self):
        self.signal = None
        self._previous = {}

    @property
    def requested(self):
        return self.signal is not None

    def _handler(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.signal = signal.Signals(signum)

    def install(self):
        try:
            for number in self.SIGNALS:
                self._previous[number] = signal.signal(number, self._handler)
        except ValueError:      # not the main thread: leave the signals alone
            self._previous = {}

    def restore(self):
        for number, previous in self._previous.items():
            signal.signal(number, previous)
        self._previous = {}


def _strerror(error):
    return (error.strerror or str(error)).lower() if isinstance(error, OSError) else str(error)


def _interrupted(signum):
    """``end_reason`` of a capture stopped by signal ``signum`` (None: not known)."""
    return "interrupted" if signum is None else f"interrupted: {signal.Signals(signum).name}"


def left_running(board: BoardClient, doing: str) -> Optional[str]:
    """A one-line warning if the board is acquiring when a command starts, as a capture
    killed with SIGKILL (which nothing can catch) leaves it, else None. ``doing`` says what
    the command does about it (``"this capture stops it and starts again"``)."""
    if not board.status()["running"]:
        return None
    return (f"the board on {board.port_name} is acquiring, and sending data that no one "
            f"records (left running by a capture that was killed?); {doing}")


def rate(events, seconds):
    """``events`` per ``seconds`` as text, in events/s, kevents/s or Mevents/s."""
    rate = events / seconds if seconds > 0 else 0.0
    if rate >= 1e6:
        return f"{rate / 1e6:.2f} Mevents/s"
    if rate >= 1e3:
        return f"{rate / 1e3:.1f} kevents/s"
    return f"{rate:.0f} events/s"


def check_reset(board: BoardClient, before: dict, now: dict) -> None:
    """Raise :exc:`~fliss.host.errors.BoardReset` if the board's STATUS ``now`` shows that it
    was reset since STATUS ``before`` of the same acquisition (or, with ``before["pulses"]``
    None, since just before its START): it stopped, or its counters went back. Reads its
    IDENTITY again first."""
    signs = []
    if not now["running"]:
        signs.append("stopped")
    if now["frames"] < before["frames"]:
        signs.append(f"its histogram count back from {before['frames']} to {now['frames']}")
    if before["pulses"] is not None and now["pulses"] < before["pulses"]:
        signs.append(f"its pulse count back from {before['pulses']} to {now['pulses']}")
    if not signs:
        return
    seq = board.last_reply.seq
    identity = board.identify()
    raise BoardReset(f"the board on {board.port_name} was reset during the capture: its STATUS "
                     f"(sequence number {seq}) shows it {', '.join(signs)}; its IDENTITY "
                     f"reads protocol {identity.protocol}, gateware {identity.gateware_version}")


#: What the progress line's rates are per second of.
_HOST_CLOCK = "(host clock)"

#: The integration time a capture takes unless told: the register's reset value (10 ms).
DEFAULT_INTEGRATION_S = BY_NAME["integration"].reset.seconds


def capture(board: BoardClient, path: str, *, mode: str = "histogram",
            integration_s: float = DEFAULT_INTEGRATION_S, acquisitions: int = 10,
            duration_s: Optional[float] = None, port: str = "",
            progress=None, watch=None, attrs=None) -> CaptureResult:
    """Capture into ``path`` from an identified :class:`~fliss.host.client.BoardClient`.

    ``mode`` is a kind of data (:data:`fliss.host.kinds.KINDS`): ``"histogram"``
    (``acquisitions`` histograms; saved as ``"image"`` when the board's frames hold several
    pixels), ``"image"`` (``acquisitions`` frames of per-pixel histograms), ``"depth"``
    (``acquisitions`` depth frames) or ``"raw"`` (events for ``duration_s``); each frame (and
    raw-mode block) integrates for ``integration_s``.
    ``progress``, if given, has ``update(done, extra="", force=False)`` and ``close()`` (as
    :class:`fliss.host.commands.capture.Progress`). Ctrl-C stops the acquisition and keeps what was
    captured; a board lost mid-capture leaves a file with everything received. Both are told
    by the result; :exc:`~fliss.host.errors.SettingsError` for an integration time shorter
    than one clock cycle, and any :exc:`~fliss.host.errors.BoardError` before the capture
    starts, are raised. ``watch``, if given, has ``add(item)``, ``add_status(status, link)``
    and ``finish(reason)`` (a live view's :class:`fliss.host.view.feed.Feed`): it sees each
    item as it is stored, the board's STATUS at each heartbeat and how the capture ended, and
    must return at once without raising. ``attrs``: more attributes of the file (name ->
    value: the sensor's ``geometry``).
    """
    clock_hz = board.identity.clock_hz
    cycles = round(integration_s * clock_hz)
    if cycles < 1:
        raise SettingsError(f"--integration {format_time(integration_s)} is shorter than one "
                            f"clock cycle of the board ({format_time(1 / clock_hz)})")
    mode, configuration, status_start = _configure(board, mode, cycles)
    # The fine TDC's calibration table, as the board holds it
    table = read_table(board, configuration) \
        if configuration["tdc_source"] == TdcSource.FINE.value else None
    run = _Capture(board, path, mode, configuration, status_start, acquisitions=acquisitions,
                   duration_s=duration_s, cycles=cycles, port=port, progress=progress,
                   watch=watch, table=table, attrs=attrs)
    reason, complete, lost = run.acquire()
    run.interrupt.install()     # again: a signal while stopping and closing only sets the flag
    try:
        run.end_progress()
        if lost is None:
            reason, complete, lost = run.stop(reason, complete)
        if lost is not None:
            run.keep_received()
        if watch is not None:
            watch.finish(reason)
        return run.close(reason, complete, lost)
    finally:
        run.interrupt.restore()


def _configure(board, mode, cycles):
    """Stop the board, set its readout and integration time (``cycles``); returns the capture
    mode (``"histogram"`` becomes ``"image"`` when a frame holds several pixels), the registers
    and the STATUS before the start. A run that would fire no pulse (keyed mode, every IV under
    the key used) is refused here, before its START."""
    board.stop()
    board.drain(quiet_s=0.1, limit_s=2.0)
    current = board.read_registers()
    kind = kind_of(mode)
    board.write_registers({"acquisition": kind.readout.value,
                           "integration": cycles}, current=current)
    configuration = board.read_registers()
    if mode == kind.readout.name.lower():
        # several pixels a frame: saved per pixel, where the kind has a form for it
        mode = mode_of(kind.readout, configuration.get("pixel_bits", 0))
    status = board.status()
    refuse_used_up(configuration, status)
    return mode, configuration, status


class _Capture:
    """One capture from its start: the file it writes, what it has stored, and the steps of
    :func:`capture` (acquire, stop, close)."""

    def __init__(self, board, path, mode, configuration, status_start, *, acquisitions,
                 duration_s, cycles, port, progress, watch=None, table=None, attrs=None):
        self.board, self.path, self.mode = board, path, mode
        self.kind = kind_of(mode)
        self.status_start, self.status_end = status_start, None
        self.acquisitions, self.duration_s = acquisitions, duration_s
        self.seconds = cycles / board.identity.clock_hz     # integration time
        attrs = {**(attrs or {}), "integration_s": self.seconds}
        if self.kind.framed:
            attrs["acquisitions_requested"] = acquisitions
        else:
            attrs["duration_s_requested"] = duration_s
        if table is not None:
            attrs["calibration_table"] = table
        try:
            self.writer = CaptureWriter(path, mode=mode, identity=board.identity.as_dict(),
                                        configuration=configuration, port=port, attrs=attrs)
        except OSError as error:
            raise PathError(f"cannot write {path}: {_strerror(error)}") from None
        self.bar = progress if progress is not None else _NoProgress()
        self.watch = watch
        self.rows = FrameRows(self.writer, acquisitions, status_start["frames"], configuration, mode)
        self.events = self.discarded = 0
        # depth captures: pixels detected, the highest peak, the last frame's threshold
        self.detections = self.highest = 0
        self.threshold = None
        self.file_error = None
        self.interrupt = _Interrupt()
        self.started = time.monotonic()

    def store(self, item):
        """Write a histogram, frame or event batch received (unless the file cannot take more,
        a full disk: then :attr:`file_error`)."""
        if self.file_error is not None:
            return
        try:
            if isinstance(item, EventBatch):
                # (every capture file keeps the events it receives: /events)
                self.writer.add_events(item)
                self.events += len(item.events)
            elif not self.kind.framed or not isinstance(item, self.kind.item):
                self.discarded += 1
            elif self.rows.add(item):
                self.kind.tally(self, item)
        except OSError as error:
            self.file_error = error

    def acquire(self):
        """Start the board and store what it sends until the capture is complete, interrupted
        or the board lost; returns ``(reason, complete, lost)``."""
        board, framed = self.board, self.kind.framed
        reason, complete, lost = "completed", True, None
        board.reset_counters()
        idle_timeout_s = max(3.0, 3 * self.seconds + 1.0)
        # Heartbeat replies keep the line busy: a board that stopped acquiring shows as no data.
        data_timeout_s = max(DATA_TIMEOUT_S, 10 * self.seconds) if framed else math.inf
        try:
            self.interrupt.install()
            board.start()
            # The pulse count starts again at START: compared between heartbeats only.
            status_last = dict(self.status_start, pulses=None)
            self.started = heartbeat = time.monotonic()
            for item in board.stream(idle_timeout_s=idle_timeout_s if framed else math.inf,
                                     data_timeout_s=data_timeout_s):
                if item is not None:
                    self.store(item)
                    if self.watch is not None:
                        self.watch.add(item)
                if self.interrupt.requested:
                    raise KeyboardInterrupt
                if self.file_error is not None or self._progress():
                    break
                now = time.monotonic()
                # (once what was read is stored: its reply comes after the data the board
                # sent meanwhile, which the link reads to find it)
                if now - heartbeat >= HEARTBEAT_S and not board.queued:
                    heartbeat = now
                    status = board.status()    # data that arrive meanwhile are kept
                    check_reset(board, status_last, status)
                    status_last = status
                    if self.watch is not None:
                        self.watch.add_status(status, board.link_counters())
        except KeyboardInterrupt:
            reason, complete = _interrupted(self.interrupt.signal), False
        except BoardReset as error:
            reason, complete, lost = f"board reset: {error}", False, error
        except BoardLost as error:
            reason, complete, lost = f"board lost: {error}", False, error
        finally:
            self.interrupt.restore()
        return reason, complete, lost

    def _progress(self):
        # Show the progress; True once everything asked for is in. Rates are per second of the
        # host's clock, which a simulated board lags behind.
        elapsed = time.monotonic() - self.started
        link = self.board.link_counters()
        damaged = f"{link['dropped_frames']} corrupt, {link['missing_packets']} lost"
        if self.kind.framed:
            # (a depth frame carries no event count: its pace is in frames)
            pace = (f"{self.rows.saved / elapsed:.1f} frames/s"
                    if not self.kind.counted and elapsed > 0 else rate(self.events, elapsed))
            self.bar.update(self.rows.saved, f"{pace} {_HOST_CLOCK}  link: {damaged}")
            return self.rows.done
        self.bar.update(min(elapsed, self.duration_s),
                        f"{rate(self.events, elapsed)} {_HOST_CLOCK}  link: {damaged}")
        return elapsed >= self.duration_s

    def end_progress(self):
        self.bar.update(self.rows.saved if self.kind.framed else
                        min(time.monotonic() - self.started, self.duration_s), force=True)
        self.bar.close()

    def stop(self, reason, complete):
        """Stop the board and store what it still sends; rows of zeros for the histograms it
        completed that never arrived, up to the last one asked for (unless the file cannot take
        more). Returns ``(reason, complete, lost)``."""
        board, start = self.board, self.status_start["frames"]
        try:
            board.stop()
            for item in board.settle(frames_at_start=start):
                self.store(item)
            self.status_end = board.status()
            if self.file_error is None:
                try:
                    self.rows.lose_made(self.status_end["frames"] - start)
                except OSError as error:
                    self.file_error = error
        except BoardLost as error:
            return f"board lost while stopping: {error}", False, error
        except KeyboardInterrupt:
            return _interrupted(self.interrupt.signal), False, None
        return reason, complete, None

    def keep_received(self):
        """Store what arrived before the board was lost, the histogram in progress included."""
        for item in self.board.take_data() + self.board.assembler.flush():
            self.store(item)

    def close(self, reason, complete, lost):
        """Write the counters, close the file; returns the :class:`CaptureResult`."""
        board, rows, writer = self.board, self.rows, self.writer
        link = board.link_counters()
        stream = board.assembler.counters.as_dict()
        stream["discarded_frames"] = self.discarded + rows.discarded
        stream["lost_rows"] = rows.lost
        stream["incomplete_rows"] = rows.incomplete
        writer.set_counters("link", link)
        writer.set_counters("stream", stream)
        writer.set_counters("board_start", self.status_start)
        if self.status_end is not None:
            writer.set_counters("board_end", self.status_end)
        if self.file_error is not None:
            reason, complete = f"cannot write {self.path}: {_strerror(self.file_error)}", False
        try:
            writer.close(reason, complete=complete, capture_s=time.monotonic() - self.started)
        except OSError as error:
            self.file_error = self.file_error or error
        result = CaptureResult(
            path=str(self.path), mode=self.mode, histograms=rows.saved,
            lost_histograms=rows.lost, events=writer.events,
            batches=writer.batches, reason=reason, complete=complete, lost=lost, link=link,
            stream=stream, status_start=self.status_start, status_end=self.status_end,
            detections=self.detections, highest=self.highest, threshold=self.threshold)
        if self.file_error is not None:
            raise PathError(f"cannot write {self.path}: {_strerror(self.file_error)}; the "
                            f"board was stopped, and the file holds the {result.what} written "
                            f"before")
        return result
