"""``fliss capture``: histograms or raw events from a board into an HDF5 file."""

import argparse
import math
import os
import signal
import sys
import time

from ..hdl.registers import AcquisitionMode
from .cli import UserError
from .errors import BoardLost
from .port_options import add_port_arguments, connect
from .stream import EventBatch, HistogramFrame
from .fileformat import CaptureWriter
from .units import format_time, parse_time


__all__ = ["register", "run", "Progress", "capture"]


#: Seconds between STATUS requests during a capture (a heartbeat that finds a silent board).
HEARTBEAT_S = 1.0


class Progress:
    """A one-line progress bar on a stream (stderr), redrawn at most ten times a second."""

    def __init__(self, total, unit, *, stream=None, enabled=True, width=24):
        self.total, self.unit = total, unit
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        self.width = width
        self._drawn = 0.0
        self._length = 0

    def update(self, done, extra="", force=False):
        if not self.enabled:
            return
        now = time.monotonic()
        if not force and now - self._drawn < 0.1:
            return
        self._drawn = now
        fraction = min(max(done / self.total, 0.0), 1.0) if self.total else 0.0
        filled = int(round(fraction * self.width))
        shown = f"{done:.1f}/{self.total:g}" if isinstance(done, float) else \
            f"{done}/{self.total}"
        line = f"[{'#' * filled}{'.' * (self.width - filled)}] {shown} {self.unit} {extra}"
        pad = max(self._length - len(line), 0)
        self.stream.write("\r" + line + " " * pad)
        self.stream.flush()
        self._length = len(line)

    def close(self):
        if self.enabled and self._length:
            self.stream.write("\n")
            self.stream.flush()


class _Interrupt:
    """Ctrl-C during a capture only sets a flag, checked between packets, so that it never
    breaks into the middle of an HDF5 write (h5py holds a lock then) or of a packet's
    decoding. A second Ctrl-C interrupts at once."""

    def __init__(self):
        self.requested = False
        self._previous = None

    def _handler(self, signum, frame):
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True

    def install(self):
        try:
            self._previous = signal.signal(signal.SIGINT, self._handler)
        except ValueError:      # not the main thread: leave Ctrl-C alone
            self._previous = None

    def restore(self):
        if self._previous is not None:
            signal.signal(signal.SIGINT, self._previous)
            self._previous = None


def _rate(events, seconds):
    rate = events / seconds if seconds > 0 else 0.0
    if rate >= 1e6:
        return f"{rate / 1e6:.2f} Mevents/s"
    if rate >= 1e3:
        return f"{rate / 1e3:.1f} kevents/s"
    return f"{rate:.0f} events/s"


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "capture", formatter_class=formatter,
        help="capture histograms or raw events into an HDF5 file",
        description="Sets the acquisition mode and integration time, starts the board, and "
                    "writes what it sends to FILE as it arrives (schema: docs/file-format.md), "
                    "with the board's configuration and identity and the link's counters. "
                    "Ctrl-C stops the acquisition on the board and keeps what was captured; a "
                    "board that stops answering leaves a file with everything received.")
    add_port_arguments(parser)
    parser.add_argument("--mode", choices=["histogram", "raw"], default="histogram",
                        help="histograms made on the board, or every event")
    parser.add_argument("--integration", default="10ms", metavar="TIME",
                        help="integration time of each histogram (and raw-mode block)")
    parser.add_argument("--acquisitions", type=int, default=10, metavar="N",
                        help="histograms to capture (histogram mode)")
    parser.add_argument("--duration", default="1s", metavar="TIME",
                        help="how long to capture (raw mode)")
    parser.add_argument("--output", "-o", required=True, metavar="FILE.h5",
                        default=argparse.SUPPRESS,
                        help="HDF5 file to write")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing FILE")
    parser.set_defaults(run=run)


def _time(text, flag):
    try:
        return parse_time(text)
    except ValueError as error:
        raise UserError(f"{flag}: {error}") from None


def run(args):
    integration_s = _time(args.integration, "--integration")
    duration_s = _time(args.duration, "--duration") if args.mode == "raw" else None
    if args.mode == "histogram" and args.acquisitions < 1:
        raise UserError(f"--acquisitions must be at least 1, not {args.acquisitions}")
    directory = os.path.dirname(os.path.abspath(args.output))
    if not os.path.isdir(directory):
        raise UserError(f"cannot write {args.output}: no directory {directory}")
    if os.path.exists(args.output) and not args.overwrite:
        raise UserError(f"{args.output} exists (use --overwrite to replace it)")
    quiet = getattr(args, "quiet", 0) > 0
    with connect(args) as board:
        return capture(board, args.output, mode=args.mode, integration_s=integration_s,
                       acquisitions=args.acquisitions, duration_s=duration_s, port=args.port,
                       progress=not quiet, quiet=quiet)


def capture(board, path, *, mode="histogram", integration_s=10e-3, acquisitions=10,
            duration_s=None, port="", progress=True, quiet=False, out=None):
    """Capture into ``path`` from an identified :class:`~fliss.host.client.BoardClient`.

    Returns the exit status: 0 when done, 130 when interrupted (Ctrl-C); raises
    :exc:`UserError` (after saving the file) when the board was lost.
    """
    out = sys.stdout if out is None else out
    clock_hz = board.identity.clock_hz
    cycles = round(integration_s * clock_hz)
    if cycles < 1:
        raise UserError(f"--integration {format_time(integration_s)} is shorter than one clock "
                        f"cycle of the board ({format_time(1 / clock_hz)})")
    board.stop()
    board.drain(quiet_s=0.1, limit_s=2.0)
    current = board.read_registers()
    board.write_registers({"acquisition": AcquisitionMode[mode.upper()].value,
                           "integration": cycles}, current=current)
    configuration = board.read_registers()
    status_start = board.status()

    writer = CaptureWriter(path, mode=mode, identity=board.identity.as_dict(),
                           configuration=configuration, port=port)
    writer.file.attrs["integration_s"] = cycles / clock_hz
    if mode == "histogram":
        writer.file.attrs["acquisitions_requested"] = acquisitions
        bar = Progress(acquisitions, "histograms", enabled=progress)
    else:
        writer.file.attrs["duration_s_requested"] = duration_s
        bar = Progress(round(duration_s, 1), "s", enabled=progress)

    state = {"events": 0, "histograms": 0, "discarded": 0}

    def store(item):
        if isinstance(item, HistogramFrame):
            if mode != "histogram" or state["histograms"] >= acquisitions:
                state["discarded"] += 1
                return
            if writer.add_histogram(item):
                state["histograms"] += 1
                state["events"] += int(item.counts.sum())
            else:
                state["discarded"] += 1
        elif isinstance(item, EventBatch):
            writer.add_events(item)
            state["events"] += len(item.events)

    reason, complete, lost = "completed", True, None
    interrupt = _Interrupt()
    board.reset_counters()
    started = time.monotonic()
    heartbeat = started
    status_end = None
    idle_timeout_s = max(3.0, 3 * cycles / clock_hz + 1.0)
    try:
        interrupt.install()
        board.start()
        started = heartbeat = time.monotonic()
        for item in board.stream(idle_timeout_s=idle_timeout_s if mode == "histogram"
                                 else math.inf):
            if item is not None:
                store(item)
            if interrupt.requested:
                raise KeyboardInterrupt
            now = time.monotonic()
            elapsed = now - started
            link = board.link_counters()
            stream = board.assembler.counters
            damaged = f"{link['dropped_frames']} corrupt, {link['missing_packets']} lost"
            if mode == "histogram":
                seen = state["histograms"] + state["discarded"] + stream.lost_frames
                bar.update(min(state["histograms"], acquisitions),
                           f"{_rate(state['events'], elapsed)}  link: {damaged}")
                if seen >= acquisitions:
                    break
            else:
                bar.update(min(elapsed, duration_s),
                           f"{_rate(state['events'], elapsed)}  link: {damaged}")
                if elapsed >= duration_s:
                    break
            if now - heartbeat >= HEARTBEAT_S:
                heartbeat = now
                board.status()    # data that arrive meanwhile are kept
    except KeyboardInterrupt:
        reason, complete = "interrupted", False
    except BoardLost as error:
        reason, complete, lost = f"board lost: {error}", False, error
    finally:
        interrupt.restore()
    bar.update(state["histograms"] if mode == "histogram" else
               min(time.monotonic() - started, duration_s), force=True)
    bar.close()

    if lost is None:
        try:
            board.stop()
            for item in board.settle():
                store(item)
            status_end = board.status()
        except BoardLost as error:
            reason, complete, lost = f"board lost while stopping: {error}", False, error
        except KeyboardInterrupt:
            reason, complete = "interrupted", False
    if lost is not None:
        for item in board.take_data() + board.assembler.flush():
            store(item)

    link = board.link_counters()
    stream = board.assembler.counters.as_dict()
    stream["discarded_frames"] = state["discarded"]
    writer.set_counters("link", link)
    writer.set_counters("stream", stream)
    writer.set_counters("board_start", status_start)
    if status_end is not None:
        writer.set_counters("board_end", status_end)
    writer.close(reason, complete=complete, capture_s=time.monotonic() - started)

    what = f"{state['histograms']} histograms" if mode == "histogram" else \
        f"{writer.events} events in {writer.batches} packets"
    damaged = link["dropped_frames"] + link["missing_packets"]
    board_dropped = 0
    if status_end is not None:
        board_dropped = sum(status_end[name] - status_start.get(name, 0) for name in
                            ("dropped_fifo", "dropped_overrun", "dropped_histogram"))
    if not quiet:
        print(f"saved {what} to {path}", file=out)
        print(f"link: {link['bytes']} bytes, {link['packets']} packets, "
              f"{link['dropped_frames']} corrupt frames dropped, "
              f"{link['missing_packets']} packets missing, "
              f"{stream['incomplete_frames']} incomplete histograms, "
              f"{stream['lost_frames']} histograms lost", file=out)
        if status_end is not None:
            print(f"board: {status_end['events'] - status_start['events']} events accepted, "
                  f"{board_dropped} dropped on the board, "
                  f"{status_end['frames'] - status_start['frames']} histograms", file=out)
    if damaged:
        print(f"fliss: warning: {link['dropped_frames']} corrupt frames and "
              f"{link['missing_packets']} missing packets on the link (counted in the file)",
              file=sys.stderr)
    if board_dropped:
        advice = ("the link is too slow for this event rate; use a higher baud rate or "
                  "histogram mode") if mode == "raw" else \
            ("events arrived while no histogram was filling, as the previous one was still "
             "being sent; use a longer integration time, a larger bin shift or a higher baud "
             "rate")
        print(f"fliss: warning: {board_dropped} events dropped on the board (counted in the "
              f"file): {advice}", file=sys.stderr)
    if lost is not None:
        raise UserError(f"{lost}; saved what was received ({what}) to {path}")
    if reason == "interrupted":
        print("fliss: interrupted; acquisition stopped, capture saved", file=sys.stderr)
        return 130
    return 0
