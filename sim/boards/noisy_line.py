"""A noisy line: a proxy between a host and a board that injects faults into the bytes it carries.

:class:`NoisyLine` opens the board's port (a pty of the model board or of the virtual board, a
USB serial port, any :func:`serial.serial_for_url` URL) and offers the host a new pty. Every
byte it forwards goes through a :class:`FaultInjector`, one per direction, which flips bits at
a bit error rate, drops and duplicates bytes, and stalls the line (no bytes for a while), with
its own seed, and counts what it did (:class:`FaultCounts`). The faults depend only on the seed
and on the position of each byte in its direction's stream, never on how the bytes were split
into reads: a run is reproducible.

``python -m fliss.sim.boards.noisy_line --port /dev/ttyUSB1 --line-errors 1e-4`` puts one in front of
a real board; the model board (``python -m fliss.sim.boards.model --line-errors 1e-4``) and the
virtual board (``fliss board --line-errors 1e-4``) put one in front of themselves.
"""

import argparse
import os
import select
import signal
import threading
import time
import tty
from dataclasses import dataclass, field, fields

import numpy as np

from ...hdl.protocol import DEFAULT_BAUD
from .pty_server import close_pty


__all__ = ["LineFaults", "FaultCounts", "FaultInjector", "NoisyLine", "add_line_arguments",
           "faults_from_args", "main"]


#: Draws per byte: 8 bits, drop, duplicate, stall.
_DRAWS = 11


@dataclass(frozen=True)
class LineFaults:
    """Faults of one direction of a line, as probabilities per bit or per byte.

    Parameters
    ----------
    bit_error_rate : float
        Probability that a bit is flipped.
    drop_rate, duplicate_rate : float
        Probability that a byte is dropped, or sent twice.
    stall_rate : float
        Probability that the line stalls after a byte (sends nothing for ``stall_s``).
    stall_s : float
        Length of a stall, in seconds.
    """
    bit_error_rate: float = 0.0
    drop_rate: float = 0.0
    duplicate_rate: float = 0.0
    stall_rate: float = 0.0
    stall_s: float = 0.5

    def __post_init__(self):
        for item in fields(self):
            value = getattr(self, item.name)
            if item.name == "stall_s":
                if not value >= 0:
                    raise ValueError(f"stall time must be at least 0 s, not {value!r}")
            elif not 0 <= value <= 1:
                raise ValueError(f"{item.name.replace('_', ' ')} must be from 0 to 1, "
                                 f"not {value!r}")

    @property
    def active(self):
        return bool(self.bit_error_rate or self.drop_rate or self.duplicate_rate or
                    self.stall_rate)


@dataclass
class FaultCounts:
    """What a :class:`FaultInjector` did."""
    bytes_in: int = 0
    bytes_out: int = 0
    bits_flipped: int = 0
    bytes_damaged: int = 0       # bytes with at least one flipped bit
    bytes_dropped: int = 0
    bytes_duplicated: int = 0
    stalls: int = 0

    def as_dict(self):
        return dict(self.__dict__)


@dataclass
class FaultInjector:
    """Applies :class:`LineFaults` to a stream of bytes, seeded by ``seed``.

    Each byte takes the same number of random draws whatever happens to it, so the faults at
    byte ``n`` of the stream depend on ``seed`` and ``n`` only. A dropped byte is not also
    damaged or duplicated; a duplicated byte is sent twice with the same damage.
    """
    faults: LineFaults
    seed: int = 0
    counts: FaultCounts = field(default_factory=FaultCounts)

    def __post_init__(self):
        self._rng = np.random.default_rng(self.seed)
        #: Offsets in the incoming stream of the bytes damaged, dropped or duplicated.
        self.faulty_offsets = []

    def apply(self, data):
        """Returns ``(out, stalls)``: the bytes to send, and the offsets in ``out`` after which
        the line stalls."""
        f, counts = self.faults, self.counts
        counts.bytes_in += len(data)
        if not data:
            return b"", []
        if not f.active:
            counts.bytes_out += len(data)
            return bytes(data), []
        draws = self._rng.random((len(data), _DRAWS))
        flips = draws[:, :8] < f.bit_error_rate
        masks = np.packbits(flips, axis=1, bitorder="little")[:, 0]
        drop = draws[:, 8] < f.drop_rate
        duplicate = (draws[:, 9] < f.duplicate_rate) & ~drop
        stall = draws[:, 10] < f.stall_rate
        masks[drop] = 0
        values = np.frombuffer(bytes(data), dtype=np.uint8) ^ masks
        repeats = np.where(drop, 0, np.where(duplicate, 2, 1))
        out = np.repeat(values, repeats)
        ends = np.cumsum(repeats)
        stalls = [int(end) for end in ends[stall]]
        faulty = np.flatnonzero((masks != 0) | drop | duplicate)
        self.faulty_offsets.extend((faulty + counts.bytes_in - len(data)).tolist())
        counts.bits_flipped += int(np.count_nonzero(flips[~drop]))
        counts.bytes_damaged += int(np.count_nonzero(masks))
        counts.bytes_dropped += int(np.count_nonzero(drop))
        counts.bytes_duplicated += int(np.count_nonzero(duplicate))
        counts.stalls += len(stalls)
        counts.bytes_out += len(out)
        return out.tobytes(), stalls


class NoisyLine:
    """A proxy on a pty, in front of the board on ``port``, with faults in each direction.

    Parameters
    ----------
    port : str
        The board's port: a device or pty path, or a :func:`serial.serial_for_url` URL.
    to_host, to_board : LineFaults
        Faults of the bytes the board sends, and of the bytes the host sends.
    seed : int
        Seed of both directions' faults (each direction draws from its own stream).
    baud : int
        Baud rate to open ``port`` at (a pty ignores it).

    :attr:`path` is the pty for the host; :attr:`to_host` and :attr:`to_board` are the two
    :class:`FaultInjector`\\ s with their counts.
    """

    def __init__(self, port, *, to_host=LineFaults(), to_board=LineFaults(), seed=0,
                 baud=DEFAULT_BAUD):
        self.port = port
        self.baud = baud
        sequence = np.random.SeedSequence(seed)
        up, down = sequence.spawn(2)
        self.to_board = FaultInjector(to_board, up)
        self.to_host = FaultInjector(to_host, down)
        self.path = None
        self._serial = None
        self._master = self._slave = None
        self._stop = threading.Event()
        self._threads = []
        self.error = None

    def open(self):
        """Open the board's port and the host's pty, start forwarding; returns the pty path."""
        import serial
        self._serial = serial.serial_for_url(self.port, baudrate=self.baud, timeout=0.02)
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self._threads = [
            threading.Thread(target=self._forward_up, name="fliss-line-up", daemon=True),
            threading.Thread(target=self._forward_down, name="fliss-line-down", daemon=True)]
        for thread in self._threads:
            thread.start()
        return self.path

    def close(self):
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=5)
        close_pty(self._master, self._slave)
        self._master = self._slave = None
        if self._serial is not None:
            self._serial.close()

    def __enter__(self):
        self.open()
        return self

    def __exit__(self, *exc):
        self.close()

    @property
    def running(self):
        return all(thread.is_alive() for thread in self._threads)

    def counts(self):
        """Both directions' :class:`FaultCounts` as dicts, ``{"to_host": ..., "to_board": ...}``."""
        return {"to_host": self.to_host.counts.as_dict(),
                "to_board": self.to_board.counts.as_dict()}

    def _pass(self, injector, data, write):
        out, stalls = injector.apply(data)
        start = 0
        for end in stalls:
            if end > start:
                write(out[start:end])
                start = end
            if self._stop.wait(injector.faults.stall_s):
                return
        if start < len(out):
            write(out[start:])

    def _forward_up(self):
        # Host to board.
        try:
            while not self._stop.is_set():
                readable, _, _ = select.select([self._master], [], [], 0.05)
                if readable:
                    data = os.read(self._master, 4096)
                    self._pass(self.to_board, data, self._serial.write)
        except Exception as error:   # the board or the pty went away
            self.error = error

    def _forward_down(self):
        # Board to host.
        def write(data):
            while data and not self._stop.is_set():
                _, writable, _ = select.select([], [self._master], [], 0.05)
                if writable:
                    data = data[os.write(self._master, data):]

        try:
            while not self._stop.is_set():
                data = self._serial.read(max(1, self._serial.in_waiting))
                if data:
                    self._pass(self.to_host, data, write)
        except Exception as error:
            self.error = error


def add_line_arguments(parser):
    """The options of a noisy line (``--line-errors`` ...) on an argparse ``parser``."""
    group = parser.add_argument_group(
        "noisy line", "faults injected between the host and the board, by a proxy on a new pty "
                      "(rates per bit or per byte, from 0 to 1)")
    group.add_argument("--line-errors", type=float, default=0.0, metavar="BER",
                       help="bit error rate of the line (for example 1e-4)")
    group.add_argument("--line-drop", type=float, default=0.0, metavar="RATE",
                       help="probability that a byte is lost")
    group.add_argument("--line-duplicate", type=float, default=0.0, metavar="RATE",
                       help="probability that a byte is sent twice")
    group.add_argument("--line-stall", type=float, default=0.0, metavar="RATE",
                       help="probability per byte that the line goes silent for --line-stall-s")
    group.add_argument("--line-stall-s", type=float, default=0.5, metavar="S",
                       help="length of a stall, seconds")
    group.add_argument("--line-direction", choices=["both", "to-host", "to-board"],
                       default="both", help="which direction the faults affect")
    group.add_argument("--line-seed", type=int, default=0, help="seed of the faults")


def faults_from_args(args):
    """``(to_host, to_board)`` :class:`LineFaults` from the options of
    :func:`add_line_arguments`, or None when there are no faults; ValueError with the option's
    name for a value out of range."""
    values = {}
    for option, name in (("line_errors", "bit_error_rate"), ("line_drop", "drop_rate"),
                         ("line_duplicate", "duplicate_rate"), ("line_stall", "stall_rate")):
        value = getattr(args, option)
        if not 0 <= value <= 1:
            raise ValueError(f"--{option.replace('_', '-')} must be from 0 to 1, not {value:g}")
        values[name] = value
    if not args.line_stall_s >= 0:
        raise ValueError(f"--line-stall-s must be at least 0, not {args.line_stall_s:g}")
    faults = LineFaults(**values, stall_s=args.line_stall_s)
    if not faults.active:
        return None
    none = LineFaults()
    return (faults if args.line_direction != "to-board" else none,
            faults if args.line_direction != "to-host" else none)


def describe(line):
    """One line about a :class:`NoisyLine`'s faults and what they did so far."""
    parts = []
    for name, injector in (("to host", line.to_host), ("to board", line.to_board)):
        c = injector.counts
        parts.append(f"{name}: {c.bytes_in} bytes, {c.bits_flipped} bits flipped, "
                     f"{c.bytes_dropped} dropped, {c.bytes_duplicated} duplicated, "
                     f"{c.stalls} stalls")
    return "; ".join(parts)


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="python -m fliss.sim.boards.noisy_line",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
        description="Put a noisy line in front of a board: opens PORT and prints the path of a "
                    "new pty whose bytes reach the board with faults injected; stop with Ctrl-C "
                    "(prints what the line did).")
    parser.add_argument("--port", required=True, help="the board's port (device, pty or URL)")
    parser.add_argument("--baud", type=int, default=DEFAULT_BAUD, help="baud rate of PORT")
    add_line_arguments(parser)
    args = parser.parse_args(argv)
    try:
        faults = faults_from_args(args) or (LineFaults(), LineFaults())
    except ValueError as error:
        parser.exit(2, f"{parser.prog}: error: {error}\n")
    line = NoisyLine(args.port, to_host=faults[0], to_board=faults[1], seed=args.line_seed,
                     baud=args.baud)
    signal.signal(signal.SIGTERM, _terminate)
    try:
        print(line.open(), flush=True)
    except Exception as error:
        parser.exit(1, f"{parser.prog}: error: cannot open {args.port}: {error}\n")
    try:
        while line.running:
            time.sleep(0.2)
        print(f"{parser.prog}: the line stopped: {line.error}", flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        line.close()
        print(describe(line), flush=True)
    return 0


def _terminate(number, frame):
    raise KeyboardInterrupt


if __name__ == "__main__":
    raise SystemExit(main())
