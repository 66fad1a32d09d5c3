"""The Python API of a FLISS board: settings with units in, numpy arrays out.

::

    import fliss

    with fliss.connect("/dev/ttyUSB1") as board:
        board.configure(mode="masked", mask_width=6, integration="10ms")
        result = board.acquire(20)          # result.counts (20, bins), result.time_s (bins,)
        events = board.acquire_raw("100ms")  # a numpy structured array and its time axis
        board.configure(pixels=64, bin_shift=3)
        images = board.acquire_image(10)    # images.counts (10, 64, 1024), images.pixels (64,)
        depth = board.acquire_depth(100)    # depth.depth_m (100, 64), depth.detected, ...

:func:`connect` opens the port and reads the board's identity (its clock turns times into
cycles); :class:`Board` is the layer above the protocol client
(:class:`~fliss.host.client.BoardClient`, at :attr:`Board.client`). Everything that goes wrong
raises a :exc:`~fliss.host.errors.BoardError` (:exc:`~fliss.host.errors.SettingsError` for
settings refused on the host); nothing is printed (progress and trouble on the link go to
the ``fliss.host`` loggers). Values rounded to whole clock cycles are returned by
:meth:`Board.configure` as notes, and issued as :class:`~fliss.host.settings.RoundingWarning`
(Python's :mod:`warnings`, which a notebook shows).
The ``fliss`` command uses the same calls.
"""

import contextlib
import logging
import math
import time
import warnings
from typing import Any, Iterator, Mapping, Optional

import numpy as np

from ..hdl.delay.modes import mode_row
from ..hdl.protocol import DEFAULT_BAUD, HISTOGRAM_COUNT_BITS
from ..hdl.registers import BY_NAME, AcquisitionMode
from ..protocol.events import EVENT_DTYPE
from .client import BoardClient, IdentityInfo
from .errors import BoardLost, BoardMismatch, BoardRefused, SettingsError
from .imager.results import DepthFrames, Images, acquire_depth, acquire_image
from .keyed import refuse_used_up
from .kinds import mode_of
from .paths import check_output_path
from .pointcloud.options import geometry_attribute
from .results import Events, Histogram, Histograms
from .settings import (DEFAULT_BANK_BITS, Conversion, RoundingWarning, Settings, convert, describe,
                       duration_s)
from .stream import EventBatch, HistogramFrame


__all__ = ["connect", "Board", "Histogram", "Histograms", "Events", "Images", "DepthFrames"]


_logger = logging.getLogger(__name__)

#: Seconds between STATUS requests while raw events are read (finds a board that went silent).
HEARTBEAT_S = 1.0


def connect(port: str, *, baud: int = DEFAULT_BAUD, timeout_s: Optional[float] = None,
            retries: int = 3) -> "Board":
    """Open the board on ``port`` and read its identity.

    Parameters
    ----------
    port : str
        Device (``/dev/ttyUSB1``, ``COM3``), pty of a virtual or model board (``/dev/pts/7``) or
        pyserial URL (``socket://host:port``).
    baud : int
        Baud rate of the port (ignored by ptys and sockets).
    timeout_s : float or None
        Seconds to wait for each reply to a command; None: 0.5 s, or 5 s on a pty.
    retries : int
        Times a command is re-sent when no reply comes.

    Returns
    -------
    Board
        Use it in a ``with`` block, or call :meth:`Board.close`.

    Raises
    ------
    PortError
        The port cannot be opened.
    BoardLost
        Nothing answers on it.
    BoardMismatch
        The board speaks another protocol version.
    """
    if timeout_s is not None and not timeout_s > 0:
        raise SettingsError(f"timeout_s must be positive, not {timeout_s!r}")
    if retries < 0:
        raise SettingsError(f"retries must not be negative, not {retries!r}")
    return Board(BoardClient(port, baud=baud, timeout_s=timeout_s, retries=retries))


class Board:
    """A FLISS board: settings with units, histograms and events as numpy arrays.

    Made by :func:`connect` (or from an open :class:`~fliss.host.client.BoardClient`); closes
    its port at the end of a ``with`` block.

    Attributes
    ----------
    client : BoardClient
        The protocol client underneath (registers in clock cycles, packets, counters).
    identity : IdentityInfo
        The board's identity: protocol and gateware version, clock, baud rate.
    """

    def __init__(self, client: BoardClient) -> None:
        self.client = client
        self._frames_at_start = None
        try:
            self.identity: IdentityInfo = client.identify()
        except BaseException:
            client.close()
            raise

    # Port

    @property
    def port(self) -> str:
        return self.client.port_name

    @property
    def clock_hz(self) -> int:
        """The board's clock frequency, in Hz."""
        return self.identity.clock_hz

    @property
    def bank_bits(self) -> int:
        """Address bits of the histogram bank (all pixels' bins): the board's, or
        :data:`~fliss.host.settings.DEFAULT_BANK_BITS` if its identity does not say."""
        return int(getattr(self.identity, "bank_bits", 0) or DEFAULT_BANK_BITS)

    def close(self) -> None:
        """Close the port (the board keeps running if it was acquiring: see :meth:`stop`)."""
        self.client.close()

    def __enter__(self) -> "Board":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return (f"<Board on {self.port}: gateware {self.identity.gateware_version}, "
                f"clock {self.clock_hz} Hz>")

    # Settings

    @property
    def registers(self) -> dict:
        """Every register's value, read from the board (clock cycles, codes, ...)."""
        return self.client.read_registers()

    @property
    def settings(self) -> Settings:
        """The board's settings in units, read from it: a read-only mapping
        (``settings["integration"]`` is ``"10 ms"``) that :meth:`configure` takes back."""
        return describe(self.client.read_registers(), self.clock_hz)

    def configure(self, settings: Optional[Mapping[str, Any]] = None, /, *,
                  style: str = "keyword", **more: Any) -> Conversion:
        """Change settings, given with units; the others keep their values.

        Parameters
        ----------
        settings : mapping, optional
            Settings by name, as ``**more``.
        style : {"keyword", "flag"}
            How refusals and notes name a setting: ``mask_width=17`` or ``--mask-width 17``.
        **more
            Settings by name (:data:`fliss.host.settings.OPTIONS`): times with a unit
            (``integration="10ms"``, or ``"800cycles"``; a bare number is refused), frequencies
            (``prf="1MHz"``; a unit here too), choices (``mode="masked"``, ``readout="raw"``), whole numbers
            (``mask_width=6``).

        Returns
        -------
        Conversion
            ``changes``: the registers written; ``registers``: all of them now; ``notes``: a
            line for each value rounded to whole clock cycles, with the value used (each also
            issued as a :class:`~fliss.host.settings.RoundingWarning`).

        Raises
        ------
        SettingsError
            A setting unknown, unreadable, out of range or inconsistent with the others:
            nothing is written. (:exc:`~fliss.host.errors.IvsUsedUp`: the mode set to keyed
            without a new key when the board's keyed source has used every IV under its key.)
        BoardRefused
            The board's build does not take a value.
        """
        values = dict(settings or {}, **more)
        current = self.client.read_registers()
        conversion = convert(values, self.clock_hz, current, style=style,
                             bank_bits=self.bank_bits)
        if "delay_mode" in conversion.said and not {"key0", "key1", "key2"} & set(
                conversion.changes):
            # keyed mode chosen without a new key, when every IV under the key is used
            refuse_used_up(conversion.registers, self.client.status())
        for note in conversion.notes:
            warnings.warn(note, RoundingWarning, stacklevel=2)
        if conversion.changes:
            try:
                # (checked by `convert`, as `write_registers` would check it again)
                self.client.write_checked(conversion.registers, conversion.changes)
            except BoardRefused as error:
                # A smaller build's maximum: say which setting, as the caller wrote it.
                name = error.register.name if error.register is not None else None
                if name not in conversion.said:
                    raise
                raise BoardRefused(
                    f"{conversion.said[name]}: the board's build does not take it (a smaller "
                    f"build, such as the iCEBreaker's, leaves out some features and narrows some "
                    f"ranges: see docs/boards.md)", command=error.command, code=error.code,
                    detail=error.detail, register=error.register) from None
            kept = self.client.read_registers(list(conversion.changes))
            # The key reads 0 (write-only), the IV reads as the IV in use, and table_data as
            # the calibration table's entry at its pointer (moved on by the write).
            lost = [name for name, value in conversion.changes.items() if kept[name] != value
                    and not BY_NAME[name].write_only and not BY_NAME[name].in_use
                    and name != "table_data"]
            if lost:
                raise BoardMismatch(f"the board on {self.port} did not keep {', '.join(lost)}")
        return conversion

    # Acquiring

    def status(self) -> dict:
        """The board's counters (STATUS): events, drops, histograms, running."""
        return self.client.status()

    def stop(self) -> None:
        """Stop acquiring and read what the board still sends."""
        self.client.stop()
        self.client.drain(quiet_s=0.1, limit_s=2.0)

    def _start(self, readout: AcquisitionMode) -> Settings:
        # Stop, switch to ``readout``, start; the settings acquired with.
        self.stop()
        registers = self.client.read_registers()
        if registers["acquisition"] != readout.value:
            registers = self.client.write_registers({"acquisition": readout.value},
                                                    current=registers)
        # (what settle waits for: the frames made from here on)
        status = self.client.status()
        refuse_used_up(registers, status)       # (keyed mode, every IV under the key used)
        self._frames_at_start = status["frames"]
        self.client.reset_counters()
        self.client.start()
        return describe(registers, self.clock_hz)

    @contextlib.contextmanager
    def _stopping(self, batches=None):
        # Stop the board after an acquisition (and an interrupted one), unless it was lost;
        # the event batches it still sends go to ``batches``.
        try:
            yield
        except BoardLost:
            raise
        except BaseException:
            self._stop_quietly()
            raise
        self.client.stop()
        for item in self.client.settle(frames_at_start=self._frames_at_start):
            if batches is not None and isinstance(item, EventBatch):
                batches.append(item.events)

    def _stop_quietly(self):
        try:
            self.client.stop()
        except BoardLost:
            pass

    def wait_s(self, settings: Optional[Settings] = None) -> float:
        """Seconds to wait for the next histogram before giving the board up: two integration
        times, the time the link takes to carry a histogram ten times over, and a reply
        timeout."""
        settings = self.settings if settings is None else settings
        link_bits = settings.pixels * settings.bins * (HISTOGRAM_COUNT_BITS + 8) * 10 // 8
        return 2 * settings.integration_s + 10 * link_bits / self.identity.baud + \
            max(2.0, self.client.timeout_s)

    def stream(self, n: Optional[int] = None, *,
               timeout_s: Optional[float] = None) -> Iterator[Histogram]:
        """Histograms as they arrive, ``n`` of them (None: until the loop stops); the board is
        switched to histogram readout and started, and stopped at the end.

        Parameters
        ----------
        n : int or None
            Histograms to yield.
        timeout_s : float or None
            Seconds to wait for each histogram; None: :meth:`wait_s`, from the integration time.

        Raises
        ------
        BoardLost
            No histogram in ``timeout_s``, or the port went away.
        """
        if n is not None and n < 1:
            raise SettingsError(f"n must be at least 1, not {n!r}")
        pixels = self.settings.pixels
        if pixels > 1:
            raise SettingsError(f"the board histograms {pixels} pixels a frame: use "
                                f"acquire_image(n), or configure(pixels=1)")
        settings = self._start(AcquisitionMode.HISTOGRAM)
        wait = self.wait_s(settings) if timeout_s is None else float(timeout_s)
        time_s = settings.time_s
        done = 0
        with self._stopping():
            for item in self.client.stream(idle_timeout_s=wait, data_timeout_s=wait):
                if not isinstance(item, HistogramFrame):
                    continue
                if not item.complete:
                    _logger.warning("histogram %d arrived incomplete: %d bins lost on the link",
                                    item.frame, item.missing_bins)
                yield Histogram(item.counts, time_s, item.frame, item.complete)
                done += 1
                if n is not None and done >= n:
                    break

    def acquire(self, n: int = 1, *, timeout_s: Optional[float] = None) -> Histograms:
        """``n`` histograms, at the board's settings (see :meth:`configure`).

        Parameters
        ----------
        n : int
            Histograms to acquire.
        timeout_s : float or None
            Seconds to wait for each histogram; None: :meth:`wait_s`.

        Returns
        -------
        Histograms
            ``counts`` ``(n, bins)`` and ``time_s`` ``(bins,)``, with frame numbers and the
            settings used.
        """
        rows = list(self.stream(n, timeout_s=timeout_s))
        settings = self.settings
        result = Histograms(counts=np.stack([row.counts for row in rows]),
                          time_s=settings.time_s,
                          frames=np.array([row.frame for row in rows], dtype=np.uint32),
                          complete=np.array([row.complete for row in rows]),
                          settings=settings)
        if result.lost:
            _logger.warning("%d histograms were lost on the link between the first and the "
                            "last of %d", result.lost, n)
        return result

    def acquire_image(self, n: int = 1, *, timeout_s: Optional[float] = None) -> Images:
        """``n`` frames of per-pixel histograms at the board's settings (``pixels``,
        ``first_pixel``, ``bin_shift``: see :meth:`configure`), in histogram readout.

        Returns
        -------
        Images
            ``counts`` ``(n, P, N)``, ``pixels`` (addresses), ``time_s`` ``(N,)``, ``frames``,
            ``complete`` and the settings used.
        """
        return acquire_image(self, n, timeout_s=timeout_s)

    def acquire_depth(self, n: int = 1, *, timeout_s: Optional[float] = None) -> DepthFrames:
        """``n`` depth frames at the board's settings (``depth_filter``, ``depth_threshold``),
        in depth readout.

        Returns
        -------
        DepthFrames
            ``depth_m``, ``height``, ``background``, ``detected`` ``(n, P)``, ``pixels``,
            ``frames`` and the settings used.
        """
        return acquire_depth(self, n, timeout_s=timeout_s)

    def acquire_raw(self, duration: str) -> Events:
        """Every event for ``duration`` (with a unit: ``"100ms"``) of the host's clock, in raw
        readout.

        The board sends events in blocks of the integration time; a block in progress at the
        end is sent when the board stops and is kept. A simulated board, slower than real
        time, acquires for less than ``duration``: ``duration_s`` of the result is the board's
        time.

        Returns
        -------
        Events
            The events as a structured array, with their time axis, the board's drops, the
            pulses it fired and its time they span.
        """
        duration_s = _duration(duration)
        start = self.client.status()
        registers = self.client.read_registers()
        settings = self._start(AcquisitionMode.RAW)
        batches = []
        started = heartbeat = time.monotonic()
        with self._stopping(batches):
            # Raw readout sends nothing while no events come: the heartbeat finds a dead board.
            for item in self.client.stream(idle_timeout_s=math.inf):
                if isinstance(item, EventBatch):
                    batches.append(item.events)
                now = time.monotonic()
                if now - started >= duration_s:
                    break
                if now - heartbeat >= HEARTBEAT_S:
                    heartbeat = now
                    self.client.status()
        end = self.client.status()
        dropped = sum(end[name] - start[name] for name in ("dropped_fifo", "dropped_overrun"))
        events = np.concatenate(batches) if batches else np.zeros(0, EVENT_DTYPE)
        # (the board's pulse count starts again at START)
        return Events(events=events, duration_s=float(end["pulses"] * _mean_interval(registers)
                                                      / self.clock_hz),
                      dropped=int(dropped), settings=settings, pulses=end["pulses"])

    def capture(self, path: str, *, acquisitions: int = 10, duration: str = "1s",
                progress=None, image: Optional[bool] = None, overwrite: bool = False,
                watch=None, geometry=None):
        """Capture into an HDF5 file (docs/file-format.md) at the board's settings: its
        readout (``acquisitions`` histograms or depth frames, or raw events for ``duration``),
        its integration time; the file records the registers used. Histograms are saved per
        pixel (``image``) when ``image`` is True, or None and a frame has several pixels.
        ``progress`` and ``watch`` (a live view's feed) as in
        :func:`fliss.host.acquisition.capture`. An existing file is replaced only with
        ``overwrite``. ``geometry``, a :class:`~fliss.host.pointcloud.geometry.SensorGeometry`
        (or its JSON, as ``fliss capture`` records it), is recorded for the depth frames'
        points (docs/point-clouds.md).

        Returns
        -------
        CaptureResult

        Raises
        ------
        PathError
            ``path`` exists (without ``overwrite``) or cannot be written; nothing is started.
        """
        from .acquisition import capture

        check_output_path(path, overwrite=overwrite, flag="path",
                          overwrite_flag="overwrite=True")
        duration_s = _duration(duration)
        registers = self.client.read_registers()
        readout = mode_of(AcquisitionMode(registers["acquisition"]), registers["pixel_bits"], image)
        attrs = {}
        if geometry is not None:
            attrs["geometry"] = geometry if isinstance(geometry, str) else \
                geometry_attribute(geometry)
        return capture(self.client, path, mode=readout,
                       integration_s=registers["integration"] / self.clock_hz,
                       acquisitions=acquisitions, duration_s=duration_s, port=self.port,
                       progress=progress, watch=watch, attrs=attrs)


def _duration(value):
    return duration_s(value, f"duration={value!r}")


def _mean_interval(registers):
    """Mean clock cycles between two of the victim's pulses at ``registers``: the period, plus
    the mean delay in interval mode (in grid mode pulse ``k`` fires at ``k T + R``)."""
    if registers["grid"]:
        return registers["period"]
    row = mode_row(registers["delay_mode"])
    return registers["period"] + row.mean_delay(length=registers["length"],
                                                mask_width=registers["mask_width"])
