"""What the live view shows: a :class:`Feed` that an acquisition (or a replay) hands every item it
receives, and the :class:`Picture` and :class:`Status` of it that the pages draw.

Two threads share a feed. The acquisition's calls :meth:`Feed.add` for each histogram, depth
frame or event batch, and :meth:`Feed.add_status` at each heartbeat: they keep references and
running totals, replace whole objects rather than change them in place, take no lock and never
raise, so an acquisition that feeds a view runs as it would without one. The server's thread
asks for :meth:`Feed.picture` and :meth:`Feed.status` at each page update: the analysis (peaks,
suppression, per-pixel depth) runs there, once per new frame for every page together.
"""

import logging
import math
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Optional, Tuple

import numpy as np

from ...hdl.event import TIMESTAMP_BITS
from ...hdl.registers import AcquisitionMode
from ..analysis import analyze
from ..imager.analysis import pixel_peak
from ..imager.results import C_M_S, depth_m, tof_s
from ..kinds import KINDS, mode_of
from ..settings import code_s as code_seconds
from ..stream import HistogramFrame


__all__ = ["READOUTS", "Setup", "PeakRow", "Picture", "Status", "Feed"]

_logger = logging.getLogger(__name__)

#: Readouts the view shows: every kind of data (histograms, per-pixel histograms, depth frames,
#: raw events).
READOUTS = tuple(KINDS)

#: The kind of data of each type of item (of kinds that share one, the first).
_KIND_OF_ITEM = {kind.item: kind for kind in reversed(KINDS.values())}

#: Board counters of events lost against the settings' wishes (not the gate's or the filters').
BOARD_DROPS = ("dropped_fifo", "dropped_overrun", "dropped_histogram")

#: Seconds of history the rates are measured over.
RATE_WINDOW_S = 2.0


@dataclass(frozen=True)
class Setup:
    """What is being shown: ``source`` (a port or a file, for the title), the ``readout``
    (one of :data:`READOUTS`), the integration time and the width of a timestamp code in
    seconds, the bin shift (raw events are histogrammed with it), whether the aggressor
    was on, the victim's time of flight if known, the shape of the imager's pixels as
    ``(rows, columns)`` (None: a profile), whether a board (``live``) or a file is the source,
    and the board's registers by name (``configuration``), from which the roles of the peaks
    are told as ``fliss analyze`` tells them (:mod:`fliss.host.roles`; without them, only
    ``aggressor_on`` is known, which does not tell)."""
    source: str
    readout: str
    integration_s: float
    code_s: float
    shift: int = 0
    aggressor_on: bool = False
    victim_s: Optional[float] = None
    shape: Optional[Tuple[int, int]] = None
    live: bool = True
    configuration: Optional[dict] = field(default=None, compare=False)

    @property
    def kind(self):
        """The kind of data shown (:class:`fliss.host.kinds.DataKind`)."""
        return KINDS[self.readout]

    @classmethod
    def of_registers(cls, source, registers, clock_hz, **more):
        """The setup of a board whose registers (by name) are ``registers``."""
        readout = mode_of(AcquisitionMode(registers["acquisition"]), registers.get("pixel_bits", 0))
        return cls(source, readout, registers["integration"] / clock_hz,
                   code_seconds(registers, clock_hz), registers.get("bin_shift", 0),
                   bool(registers.get("aggressor", 0)), configuration=dict(registers), **more)

    @classmethod
    def of_capture(cls, capture, **more):
        """The setup of a :class:`~fliss.host.fileformat.Capture` read from a file."""
        integration_s = capture.attrs.get("integration_s")
        if not integration_s and capture.clock_hz:
            integration_s = capture.configuration.get("integration", 0) / capture.clock_hz
        return cls(capture.path, capture.mode, float(integration_s or 0.0), capture.code_s,
                   capture.shift, bool(capture.configuration.get("aggressor", 0)),
                   live=False, configuration=dict(capture.configuration), **more)


@dataclass(frozen=True)
class PeakRow:
    """A row of the peak table: ``role`` is ``"victim"``, ``"aggressor"`` or ``""``."""
    role: str
    tof_ns: float
    distance_m: float
    fwhm_ns: float
    height: float


@dataclass(frozen=True)
class Picture:
    """What a page draws of the latest frame (or of the sum of the frames).

    ``counts`` is the histogram (of a frame of pixels: summed over them) against ``time_ns``,
    the centre of each bin; ``image`` the per-pixel histograms ``(P, N)`` (image readout);
    ``pixels`` the pixel addresses and ``depth_m`` and ``intensity`` their depth (NaN where
    nothing is detected) and intensity (image: counts; depth: peak height), for the imager.
    ``frame`` is the board's number of the latest frame in it, ``frames`` how many it sums.
    """
    seq: int
    summed: bool
    frame: Optional[int] = None
    frames: int = 0
    complete: bool = True
    total: int = 0
    time_ns: Optional[np.ndarray] = None
    counts: Optional[np.ndarray] = None
    image: Optional[np.ndarray] = None
    background: float = math.nan
    peaks: Tuple[PeakRow, ...] = ()
    suppression_db: Optional[float] = None
    suppression_limited: bool = False
    note: str = ""
    pixels: Optional[np.ndarray] = None
    depth_m: Optional[np.ndarray] = None
    intensity: Optional[np.ndarray] = None


@dataclass(frozen=True)
class Status:
    """Counts and rates: frames (raw events: batches) received, lost (gaps in the frame
    numbers) and incomplete; frames per second received, counts per second of integration
    (events per second for raw events), events dropped on the board per second (None before
    a STATUS reply; from a file: over the whole capture), the link's corrupt frames and
    missing packets, and the ``state`` of the source (``"acquiring"``, ``"completed"``,
    ``"board lost: ..."``)."""
    state: str
    frames: int
    lost: int
    incomplete: int
    frame_rate_hz: float
    count_rate_hz: float
    drop_rate_hz: Optional[float]
    corrupt: int
    missing: int
    events: int


class Feed:
    """The view's data, handed in by an acquisition and read by the pages."""

    def __init__(self, setup: Setup):
        if setup.readout not in READOUTS:
            raise ValueError(f"readout {setup.readout!r} is not one of {', '.join(READOUTS)}")
        self.setup = setup
        # Written by the acquisition's thread only (each a whole object, replaced):
        self._seq = 0
        self._latest = None          # the latest HistogramFrame or DepthFrame
        self._sum = (None, 0)        # (counts summed, frames in it)
        self._frames = self._lost = self._incomplete = self._events = 0
        self._last_frame = None
        self._status = None          # (time, STATUS, link counters) of the latest heartbeat
        self._first_status = None
        self._begun = None           # time of the first item
        self._state = "waiting for the first frame"
        self._broken = False
        self._clears_done = 0
        # Written by the server's thread only:
        self._clears = 0
        self._cache = {}
        self._history = deque()
        self._file_drops = None

    # The acquisition's side

    def add(self, item) -> None:
        """Take a :class:`~fliss.host.stream.HistogramFrame`, a
        :class:`~fliss.host.stream.DepthFrame` or an :class:`~fliss.host.stream.EventBatch`
        (anything else is ignored). Never raises: a view never stops an acquisition."""
        if self._broken:
            return
        try:
            self._add(item)
        except Exception as error:      # noqa: BLE001 -- logged once, the view stops
            self._broken = True
            self._state = f"the view stopped showing frames: {error}"
            _logger.warning("the view stopped showing frames (%s: %s); the acquisition goes on",
                            type(error).__name__, error)

    def _add(self, item):
        kind = _KIND_OF_ITEM.get(type(item))
        if kind is None:
            return
        seen = kind.seen(item, self.setup.shift)
        if seen.frame is None:
            self._frames += 1
        else:
            self._count_frame(seen.frame, seen.complete)
        self._events += seen.photons
        if seen.counts is not None:
            self._accumulate(seen.counts)
        if seen.latest:
            self._latest = item
        if self._seq == 0:
            self._begun = time.monotonic()
            self._state = "acquiring" if self.setup.live else "replaying"
        self._seq += 1

    def _count_frame(self, frame, complete):
        if self._last_frame is not None:
            gap = (frame - self._last_frame - 1) % (1 << 32)
            if gap < 1 << 31:
                self._lost += gap
        self._last_frame = frame
        self._frames += 1
        self._incomplete += not complete

    def _accumulate(self, counts):
        total, frames = self._sum
        if self._clears != self._clears_done or total is None or total.shape != counts.shape:
            self._clears_done = self._clears
            total, frames = np.zeros(counts.shape, np.int64), 0
        self._sum = (total + counts, frames + 1)

    def add_status(self, status: dict, link: dict) -> None:
        """Take the board's STATUS counters and the link's counters (at a heartbeat)."""
        entry = (time.monotonic(), dict(status), dict(link))
        if self._first_status is None:
            self._first_status = entry
        self._status = entry

    def finish(self, state: str) -> None:
        """The source ended: ``state`` says how (``"completed"``, ``"board lost: ..."``)."""
        self._state = state

    @property
    def seq(self) -> int:
        """Items taken so far: a new number means something new to show."""
        return self._seq

    @property
    def state(self) -> str:
        """How the source is doing: ``"acquiring"``, ``"completed"``, ``"board lost: ..."``."""
        return self._state

    def set_file_drops(self, rate_hz: Optional[float]) -> None:
        """Events dropped on the board per second over a whole capture (a replay)."""
        self._file_drops = rate_hz

    # The server's side

    def clear_sum(self) -> None:
        """Start the sum again from the next item."""
        self._clears += 1

    def picture(self, summed: bool = False) -> Picture:
        """What the pages draw: the latest frame, or the sum of the frames (since the start or
        the last :meth:`clear_sum`); analysed once per new frame."""
        seq = self._seq
        key = (summed, seq)
        if key not in self._cache:
            self._cache = {k: v for k, v in self._cache.items() if k[0] != summed}
            self._cache[key] = self._draw(seq, summed)
        return self._cache[key]

    def status(self) -> Status:
        """The counts and rates now."""
        now = time.monotonic()
        frames, events = self._frames, self._events
        history = self._history
        if not history or now - history[-1][0] >= 0.1:
            history.append((now, frames, events))
        while len(history) > 2 and now - history[1][0] >= RATE_WINDOW_S:
            history.popleft()
        then, frames_then, events_then = history[0]
        span = now - then
        frame_rate = (frames - frames_then) / span if span > 0 else 0.0
        if not self.setup.kind.framed or self.setup.integration_s <= 0:
            count_rate = (events - events_then) / span if span > 0 else 0.0
        else:
            done = frames - frames_then
            count_rate = (events - events_then) / done / self.setup.integration_s if done else \
                (self._latest_rate())
        drop_rate, corrupt, missing = self._file_drops, 0, 0
        if self._status is not None:
            at, status, link = self._status
            first_at, first, _ = self._first_status
            if at > first_at:
                drop_rate = sum(status.get(name, 0) - first.get(name, 0)
                                for name in BOARD_DROPS) / (at - first_at)
            elif self._begun is not None and at > self._begun:
                # One STATUS since the first item: the counters were cleared at the START.
                drop_rate = sum(status.get(name, 0) for name in BOARD_DROPS) / \
                    (at - self._begun)
            corrupt, missing = link.get("dropped_frames", 0), link.get("missing_packets", 0)
        return Status(self._state, frames, self._lost, self._incomplete, frame_rate,
                      count_rate, drop_rate, corrupt, missing, events)

    def _latest_rate(self):
        # Counts per second of integration of the latest frame (when none came lately).
        latest = self._latest
        if isinstance(latest, HistogramFrame) and self.setup.integration_s > 0:
            return float(latest.counts.sum()) / self.setup.integration_s
        return 0.0

    def _draw(self, seq, summed):
        setup = self.setup
        latest = self._latest
        total, frames = self._sum
        if not setup.kind.counted:
            if not isinstance(latest, setup.kind.item):
                return Picture(seq, summed)
            return self._depth_picture(seq, latest)
        if summed or not setup.kind.framed:
            if total is None:
                return Picture(seq, summed)
            image, frames = total, frames
            frame = self._last_frame
            complete = True
        else:
            if not isinstance(latest, setup.kind.item):
                return Picture(seq, summed)
            image, frames, frame, complete = latest.image, 1, latest.frame, latest.complete
            summed = False
        return self._histogram_picture(seq, summed, image, frame, frames, complete,
                                       first_pixel=getattr(latest, "first_pixel", 0))

    def _histogram_picture(self, seq, summed, image, frame, frames, complete, first_pixel):
        setup = self.setup
        bins = image.shape[-1]
        shift = TIMESTAMP_BITS - int(round(math.log2(bins)))
        bin_s = setup.code_s * (1 << shift)
        counts = image.sum(axis=0, dtype=np.int64)
        time_ns = (np.arange(bins) + 0.5) * bin_s * 1e9
        more = {}
        if len(image) > 1:
            pixels = first_pixel + np.arange(len(image))
            tofs = np.array([pixel_peak(row, bin_s, shift)[0] for row in image])
            more = dict(image=np.asarray(image), pixels=pixels, depth_m=depth_m(tofs),
                        intensity=image.sum(axis=1, dtype=np.int64))
        level, peaks, roles, result, note = math.nan, [], (), None, ""
        if counts.any():
            configuration = setup.configuration if setup.configuration is not None else \
                {"aggressor": int(setup.aggressor_on)}
            analysis = analyze(counts, bin_s, configuration=configuration,
                               victim_s=setup.victim_s, shift=shift)
            level, peaks, roles = analysis.level, analysis.peaks, analysis.roles.roles
            result, note = analysis.suppression, analysis.note
        rows = [PeakRow(role, peak.position_s * 1e9, peak.position_s * C_M_S / 2,
                        peak.fwhm_s * 1e9, peak.height) for peak, role in zip(peaks, roles)]
        return Picture(seq, summed, frame, frames, complete, int(counts.sum()), time_ns,
                       counts, background=level, peaks=tuple(rows),
                       suppression_db=None if result is None else result.s_db,
                       suppression_limited=bool(result is not None and result.limited),
                       note=note, **more)

    def _depth_picture(self, seq, frame):
        bin_s = self.setup.code_s * (1 << frame.shift)
        pixels = frame.first_pixel + np.arange(len(frame.height))
        depths = np.where(frame.detected, depth_m(tof_s(frame.position, bin_s)), np.nan)
        return Picture(seq, False, frame.frame, 1, True, pixels=pixels, depth_m=depths,
                       intensity=np.where(frame.detected, frame.height, 0))
