"""The byte side of a board model on a pseudo-terminal, with fault injection.

:class:`PtyServer` opens a pty, serves it from a thread, decodes what the host sends with
:class:`fliss.protocol.FrameDecoder` and sends packets as frames. Faults can be injected:
``kill_after`` closes the pty after that many data packets (a board unplugged mid-capture),
``hang_after`` stops sending without closing, ``reset_after`` resets the board (a power cycle:
registers, counters and sequence numbers back to their reset values, bytes not yet sent lost),
``corrupt_every`` damages one byte of every n-th
frame sent (never a delimiter, never into a delimiter), keeping the list of what it damaged in
:attr:`PtyServer.corrupted`, and ``corrupt_commands_every`` damages one byte of every n-th read
from the host. A subclass (:class:`fliss.sim.boards.model.ModelBoard`) answers the packets
(:meth:`PtyServer._receive`) and makes the data (:meth:`PtyServer._work`).
"""

import errno
import fcntl
import logging
import os
import select
import sys
import termios
import threading
import time
import traceback
import tty

import numpy as np

from ...protocol.frames import FrameDecoder, encode_frame


__all__ = ["close_pty", "PtyServer"]


logger = logging.getLogger(__name__)


def close_pty(*fds):
    """Close the file descriptors of a pty (those that are not None), whatever state they are
    in."""
    for fd in fds:
        if fd is not None:
            try:
                os.close(fd)
            except OSError:
                pass


class PtyServer:
    """A pseudo-terminal served by a thread, for a board model.

    Parameters
    ----------
    kill_after, hang_after : int or None
        Close the pty (or stop sending) once this many data packets have been sent.
    reset_after : int or None
        Reset the board (:meth:`_reset`) once this many data packets have been sent.
    corrupt_every : int or None
        Damage one byte in every n-th frame sent (data and replies).
    corrupt_seed : int
        Seed of the corruption's choices.
    corrupt_types : set of PacketType or None
        Damage only frames of these types (all by default); ``corrupt_every`` counts them.
    corrupt_commands_every : int or None
        Damage one non-delimiter byte in every n-th read from the host (commands).
    keep_sent : bool
        Keep a record of every frame sent (:attr:`sent`, :attr:`frames_out`); False for long
        runs, whose records would fill the memory.
    """

    def __init__(self, *, kill_after=None, hang_after=None, reset_after=None, corrupt_every=None,
                 corrupt_seed=1, corrupt_types=None, corrupt_commands_every=None,
                 keep_sent=True):
        self.kill_after = kill_after
        self.reset_after = reset_after
        #: Resets so far (``reset_after``, :meth:`reset`).
        self.resets = 0
        self.hang_after = hang_after
        self.corrupt_every = corrupt_every
        self._corrupt_rng = np.random.default_rng(corrupt_seed)
        self.corrupt_types = None if corrupt_types is None else frozenset(corrupt_types)
        self.corrupt_commands_every = corrupt_commands_every
        self.keep_sent = keep_sent
        #: Reads from the host in which a byte was damaged.
        self.corrupted_commands = 0
        self._reads = 0
        #: Frames damaged on the way out: ``(PacketType, seq)``.
        self.corrupted = []
        #: Every data packet sent: ``(PacketType, seq, payload)`` (before any corruption).
        self.sent = []
        #: Every frame sent (data and replies): ``(PacketType, seq, end)``, ``end`` its end in
        #: bytes from the start of the first one.
        self.frames_out = []
        self.killed = False
        self.hung = False
        #: The error that stopped the board's thread (a bug of the model, or of the library
        #: versions under it): the pty is closed, so the host sees the board lost, not silent.
        self.failed = None
        self._reset_due = False
        self._frames_sent = 0
        self._data_sent = 0         # data packets sent
        self._seq = 0
        self._out = bytearray()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        self._master = self._slave = None
        self.path = None

    # What a subclass provides

    @property
    def _busy(self):
        """True while the board makes data: the thread then looks for work more often."""
        return False

    @property
    def _due(self):
        """True when data is due already (a board behind the clock): the thread then does not
        wait for the host before it works."""
        return False

    def _receive(self, item):
        """Answer ``item``, a :class:`~fliss.protocol.Packet` or a report of the decoder."""

    def _work(self, now):
        """Make data up to wall-clock time ``now``, while the host keeps up."""

    def _killed(self):
        """The board was unplugged (``kill_after``)."""

    def _reset(self):
        """The board's own state back to reset (``reset_after``); the sequence numbers and the
        bytes not yet sent are reset here."""

    # Life cycle

    def open(self):
        """Create the pty and start serving it; returns the path of its terminal."""
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        flags = fcntl.fcntl(self._master, fcntl.F_GETFL)
        fcntl.fcntl(self._master, fcntl.F_SETFL, flags | os.O_NONBLOCK)
        self.path = os.ttyname(self._slave)
        self._thread = threading.Thread(target=self._serve, name="fliss-model-board", daemon=True)
        self._thread.start()
        return self.path

    def close(self):
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5)
        close_pty(self._master, self._slave)
        self._master = self._slave = None

    def __enter__(self):
        self.open()
        return self

    def __exit__(self, *exc):
        self.close()

    def reset(self, timeout_s=5.0):
        """Reset the board now, a power cycle as ``reset_after`` makes one (counted in
        :attr:`resets`), and return once it is done."""
        with self._lock:
            resets = self.resets
            self._reset_due = True
        deadline = time.monotonic() + timeout_s
        while self.resets == resets:
            if time.monotonic() > deadline:
                raise TimeoutError(f"the board on {self.path} did not reset in {timeout_s:g} s")
            time.sleep(0.002)

    def _serve(self):
        try:
            self._serve_frames()
        except Exception as error:
            self.failed = error
            logger.error("the model board stopped: %s", "".join(
                traceback.format_exception(type(error), error, error.__traceback__)).rstrip())
            with self._lock:
                master, self._master = self._master, None
            close_pty(master)

    def _serve_frames(self):
        decoder = FrameDecoder(synced=False)
        while not self._stop.is_set():
            timeout = 0.0 if self._due else 0.005 if self._busy or self._out else 0.05
            try:
                readable, _, _ = select.select([self._master], [], [], timeout)
            except (OSError, ValueError):
                return
            if readable:
                try:
                    data = os.read(self._master, 4096)
                except OSError as error:
                    if error.errno in (errno.EIO, errno.EAGAIN):
                        time.sleep(0.01)
                        data = b""
                    else:
                        return
                data = self._damage_commands(data)
                with self._lock:
                    for item in decoder.feed(data):
                        self._receive(item)
            with self._lock:
                self._work(time.monotonic())
                if self._reset_due:
                    # A power cycle after this packet: what is sent so far goes out first.
                    self._flush(block=True)
                    self._reset_due = False
                    self._seq = 0
                    self.resets += 1
                    self._reset()
                self._flush()
            if self.killed:
                return

    def _damage_commands(self, data):
        if not self.corrupt_commands_every or not data.strip(b"\0"):
            return data
        self._reads += 1
        if self._reads % self.corrupt_commands_every:
            return data
        data = bytearray(data)
        positions = [i for i, byte in enumerate(data) if byte]
        position = positions[int(self._corrupt_rng.integers(0, len(positions)))]
        data[position] = 0xff if data[position] != 0xff else 0x7f
        self.corrupted_commands += 1
        return bytes(data)

    # Output

    def _send(self, type, payload, data=False):
        if self.killed or self.hung:
            return
        seq = self._seq
        self._seq = (self._seq + 1) % 256
        frame = bytearray(encode_frame(type, seq, payload))
        eligible = self.corrupt_types is None or type in self.corrupt_types
        self._frames_sent += eligible
        if eligible and self.corrupt_every and self._frames_sent % self.corrupt_every == 0:
            position = int(self._corrupt_rng.integers(0, len(frame) - 1))
            value = frame[position]
            while True:
                new = int(self._corrupt_rng.integers(1, 256))
                if new != value:
                    break
            frame[position] = new
            self.corrupted.append((type, seq))
        if data and self.keep_sent:
            self.sent.append((type, seq, bytes(payload)))
        self._out += frame
        if self.keep_sent:
            self.frames_out.append((type, seq, (self.frames_out[-1][2] if self.frames_out
                                                else 0) + len(frame)))
        self._data_sent += data
        if data:
            if self.kill_after is not None and self._data_sent >= self.kill_after:
                self._flush(block=True)
                self._wait_drained()
                self.killed = True
                self._killed()
                os.close(self._master)
                self._master = None
            elif self.hang_after is not None and self._data_sent >= self.hang_after:
                self._flush(block=True)
                self.hung = True
            elif self.reset_after is not None and not self.resets and \
                    self._data_sent >= self.reset_after:
                self._reset_due = True

    def _wait_drained(self, limit_s=2.0):
        """Wait until the host has read what was sent (a pty drops it when the board goes)."""
        end = time.monotonic() + limit_s
        empty_since = None
        while time.monotonic() < end:
            waiting = int.from_bytes(fcntl.ioctl(self._slave, termios.FIONREAD, bytes(4)),
                                     sys.byteorder)
            if waiting:
                empty_since = None
            elif empty_since is None:
                empty_since = time.monotonic()
            elif time.monotonic() - empty_since > 0.1:
                # Empty for a while: also nothing left in the pty's own buffer.
                return
            time.sleep(0.005)

    def _flush(self, block=False):
        while self._out and self._master is not None:
            try:
                written = os.write(self._master, self._out)
            except BlockingIOError:
                if not block:
                    return
                time.sleep(0.001)
                continue
            except OSError:
                self._out.clear()
                return
            del self._out[:written]
