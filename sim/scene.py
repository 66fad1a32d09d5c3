"""Photon-level Monte Carlo of a TCSPC LiDAR pixel with FLISS: victim, aggressors, background.

The model follows section 5 of the paper. The victim fires at the laser rising edges that the
reference model of the delay core gives (:mod:`fliss.sim.scheduler`, the same delay sequences and
seeds as the gateware), and its TDC starts on the same edge, so the victim's own photons keep their
time of flight (equation 5) while the photons of an aggressor, fired on its own schedule, move by
``-T_rnd`` in the victim's frame (equation 6).

Model
-----
* Time runs in TDC LSBs (50 ps) as ``float64``; cycle ``0`` is the first take cycle of the victim's
  scheduler, pulse ``k`` rises (and its TDC starts) in cycle ``fire_cycles(...)[k] + LATENCY``.
* A pulsed source (the victim's own echo, each aggressor) gives per pulse a Poisson number of
  detections with mean ``detections_per_pulse``, spread as a Gaussian of the laser's FWHM around the
  pulse's arrival time, widened by the SPAD and TDC timing jitter (Gaussians add in quadrature).
  Both Gaussians are cut at :data:`TRUNCATION_SIGMAS` standard deviations.
* Ambient light and dark counts form a Poisson process of rate ``background_hz``. It is drawn only
  where it can matter: in each TDC window and in the dead time just before it.
* The SPAD is non-paralysable: after a detection it is blind for ``dead_time_s``. A photon that
  arrives while it is blind is lost (counted as ``dead``). The SPAD's state carries over from window
  to window; the background between windows is not drawn, so a chain of blocked photons reaching
  from the gap into a window is not modelled (its effect is of order ``(background_hz *
  dead_time_s)**2``).
* The TDC of pulse ``k`` is live from its start until ``2**13`` LSBs later or until the next start,
  whichever comes first; it keeps one photon per laser cycle, the first or the last detected one
  (the paper's sensor keeps the last). Photons outside every window are counted as ``outside``.
* An event is what the sensor's TDC interface delivers: timestamp ``floor((t - start) / LSB)``,
  pixel address, collision flag (always 0: one pixel is modelled) and laser cycle index ``pulse``
  (modulo ``2**32``, as the gateware counter wraps).

Every photon drawn is counted exactly once per source: ``generated = outside + dead + overwritten +
recorded``.

The simulation streams: :class:`Simulation` works through the laser cycles a chunk at a time, so
memory stays bounded whatever the integration time. The victim's TDC starts come from the
reference scheduler, or, in closed loop with a simulated gateware, from :meth:`Simulation.feed`.
:func:`acquire` cuts one continuous run into acquisitions of a given integration time and returns
their histograms (``TDC_CODES`` bins, as the histogram engine delivers them).
"""

import math
import sys
from dataclasses import dataclass, field

import numpy as np

from ..hdl import DEFAULT_CLOCK_HZ
from ..hdl.delay import MASKED_LENGTH, MASKED_STEPS
from ..hdl.event import ADDRESS_BITS, PULSE_BITS, TDC_LSB_S, TIMESTAMP_BITS
from . import delay as _delay
from . import lfsr as _lfsr
from . import scheduler as _scheduler
from .event import EVENT_DTYPE


__all__ = ["SPEED_OF_LIGHT", "TDC_CODES", "FWHM_PER_SIGMA", "TRUNCATION_SIGMAS", "COUNTERS",
           "Aggressor", "Scene", "DelayStream", "Chunk", "Simulation", "Acquisitions",
           "acquire", "histogram", "time_of_flight"]


#: Speed of light in vacuum, m/s.
SPEED_OF_LIGHT = 299_792_458.0

#: Number of TDC codes (histogram bins): ``2**13``.
TDC_CODES = 1 << TIMESTAMP_BITS

#: FWHM of a Gaussian in units of its standard deviation, ``2 * sqrt(2 * ln 2)``.
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))

#: Pulse shapes and jitter are Gaussians cut at this many standard deviations.
TRUNCATION_SIGMAS = 8.0

#: What happened to each photon, one counter per source (columns of the ``counts`` arrays).
COUNTERS = ("generated", "outside", "dead", "overwritten", "recorded")

_GENERATED, _OUTSIDE, _DEAD, _OVERWRITTEN, _RECORDED = range(len(COUNTERS))


def time_of_flight(distance_m):
    """Round-trip time of flight in seconds to a target ``distance_m`` away (``2 z / c``)."""
    return 2.0 * distance_m / SPEED_OF_LIGHT


def _check_number(value, what, *, positive=False):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value < 0 or (positive and value == 0):
        kind = "positive" if positive else "non-negative"
        raise ValueError(f"{what} must be a finite {kind} number, not {value!r}")


@dataclass(frozen=True)
class Aggressor:
    """A second pulsed emitter seen by the victim's pixel.

    Parameters
    ----------
    period_cycles : float
        Pulse period in victim clock cycles; need not be whole (an aggressor has its own clock).
        The paper runs it at the victim's effective PRF.
    offset_s : float
        Time of its pulse ``j`` after the victim's nominal (undelayed) rising edge of pulse ``j``
        when both run at the same period: its first pulse rises ``offset_s`` after cycle
        ``1 + LATENCY``. The paper uses 75 ns. May be negative.
    detections_per_pulse : float
        Mean photons per aggressor pulse that reach the victim's pixel and would be detected by a
        ready SPAD.
    fwhm_s : float
        FWHM of its Gaussian pulse.
    tof_s : float or None
        Time of flight from the aggressor over the target to the victim's pixel; ``None`` takes the
        victim's own round trip (both emitters next to each other, as on the paper's board).
    mode, length, mask_width, seed, grid
        Its own FLISS delays (see :class:`fliss.sim.scheduler.Settings`); ``mode="off"`` (the
        default) fires on a fixed period. With delays the period must be a whole number of cycles.
    """

    period_cycles: float
    offset_s: float = 75e-9
    detections_per_pulse: float = 0.05
    fwhm_s: float = 2.1e-9
    tof_s: object = None
    mode: object = "off"
    length: object = None
    mask_width: object = None
    seed: int = 1
    grid: bool = False

    def __post_init__(self):
        _check_number(self.period_cycles, "Aggressor period (victim clock cycles)", positive=True)
        if isinstance(self.offset_s, bool) or \
                not isinstance(self.offset_s, (int, float, np.integer, np.floating)) or \
                not math.isfinite(self.offset_s):
            raise ValueError(f"Aggressor offset must be a finite number of seconds, "
                             f"not {self.offset_s!r}")
        _check_number(self.detections_per_pulse, "Aggressor detections per pulse")
        _check_number(self.fwhm_s, "Aggressor pulse FWHM (s)", positive=True)
        if self.tof_s is not None:
            _check_number(self.tof_s, "Aggressor time of flight (s)")
        mode = _delay.check_settings(self.mode, length=self.length, mask_width=self.mask_width,
                                     seed=self.seed)
        if mode != _delay.DelayMode.OFF:
            if float(self.period_cycles) != int(self.period_cycles) or self.period_cycles < 2:
                raise ValueError(f"An aggressor with its own delays needs a whole number of clock "
                                 f"cycles of at least 2 as period, not {self.period_cycles!r}")
            self.settings().check()

    def settings(self):
        """Its delay settings as :class:`fliss.sim.scheduler.Settings`."""
        return _scheduler.Settings(
            mode=_delay.parse_mode(self.mode), length=self.length or 8,
            mask_width=self.mask_width or 6, seed=self.seed,
            period=int(self.period_cycles), grid=self.grid)

    @property
    def has_delays(self):
        return _delay.parse_mode(self.mode) != _delay.DelayMode.OFF


@dataclass(frozen=True)
class Scene:
    """A victim pixel looking at one target, with background and aggressors.

    Parameters
    ----------
    victim : Settings
        The victim's delay core settings (mode, L, Wm, seed, period in cycles, grid).
    clock_hz : float
        System clock of the victim.
    distance_m : float
        Target distance; the echo returns after ``2 z / c`` (4 m: 26.7 ns).
    detections_per_pulse : float
        Mean echo photons per victim pulse that a ready SPAD would detect. Keep it well below 1
        to stay out of pile-up.
    fwhm_s : float
        FWHM of the victim's Gaussian laser pulse (Table 1: 2.1 ns).
    aggressors : tuple of Aggressor
    background_hz : float
        Rate of ambient photons and dark counts at the pixel.
    dead_time_s : float
        SPAD dead time (non-paralysable).
    jitter_fwhm_s : float
        FWHM of the Gaussian timing jitter of SPAD and TDC.
    keep : str
        ``"last"`` (the paper's sensor) or ``"first"``: which detected photon the single-hit TDC
        keeps in each laser cycle.
    address : int
        Pixel address written into the events.
    """

    victim: _scheduler.Settings = _scheduler.Settings(period=80)
    clock_hz: float = DEFAULT_CLOCK_HZ
    distance_m: float = 4.0
    detections_per_pulse: float = 0.05
    fwhm_s: float = 2.1e-9
    aggressors: tuple = ()
    background_hz: float = 1e5
    dead_time_s: float = 20e-9
    jitter_fwhm_s: float = 100e-12
    keep: str = "last"
    address: int = 0

    def __post_init__(self):
        if not isinstance(self.victim, _scheduler.Settings):
            raise ValueError(f"Victim settings must be a fliss.sim.scheduler.Settings, "
                             f"not {self.victim!r}")
        self.victim.check()
        _check_number(self.clock_hz, "Clock frequency (Hz)", positive=True)
        _check_number(self.distance_m, "Target distance (m)")
        _check_number(self.detections_per_pulse, "Detections per pulse")
        _check_number(self.fwhm_s, "Pulse FWHM (s)", positive=True)
        _check_number(self.background_hz, "Background rate (Hz)")
        _check_number(self.dead_time_s, "Dead time (s)")
        _check_number(self.jitter_fwhm_s, "Jitter FWHM (s)")
        if self.keep not in ("first", "last"):
            raise ValueError(f"The TDC keeps the 'first' or the 'last' photon, not {self.keep!r}")
        if isinstance(self.address, bool) or not isinstance(self.address, (int, np.integer)) \
                or not 0 <= self.address < (1 << ADDRESS_BITS):
            raise ValueError(f"Pixel address must be an integer from 0 to "
                             f"{(1 << ADDRESS_BITS) - 1}, not {self.address!r}")
        object.__setattr__(self, "aggressors", tuple(self.aggressors))
        for aggressor in self.aggressors:
            if not isinstance(aggressor, Aggressor):
                raise ValueError(f"Aggressors must be Aggressor objects, not {aggressor!r}")

    @property
    def lsb_per_cycle(self):
        """Clock period in TDC LSBs (250 at 80 MHz)."""
        return 1.0 / (self.clock_hz * TDC_LSB_S)

    @property
    def tof_s(self):
        """The victim's round-trip time of flight, in seconds."""
        return time_of_flight(self.distance_m)

    @property
    def sources(self):
        """Names of the photon sources, in the order of the rows of the ``counts`` arrays."""
        return ("signal", "background") + tuple(f"aggressor {index + 1}"
                                                for index in range(len(self.aggressors)))

    def replace(self, **changes):
        """A copy with some fields changed."""
        from dataclasses import replace
        return replace(self, **changes)


class DelayStream:
    """The delays of a delay source after a load, continued block after block.

    ``take(n)`` returns the next ``n`` delays; consecutive calls give exactly
    :func:`fliss.sim.delay.delays` of the total count. Sequences of up to ``2**16`` pulses are
    tabulated once; longer ones advance a block of register states by a precomputed jump.
    """

    TABLE_LIMIT = 1 << 16

    def __init__(self, mode, *, length=None, mask_width=None, seed=1, block=1 << 16):
        self.mode = _delay.check_settings(mode, length=length, mask_width=mask_width, seed=seed)
        self._table = None
        self._position = 0
        if self.mode == _delay.DelayMode.OFF:
            self._table = np.zeros(1, dtype=np.int64)
            return
        period = _delay.sequence_period(self.mode, length=length, mask_width=mask_width)
        if period <= self.TABLE_LIMIT:
            self._table = _delay.delays(self.mode, period, length=length, mask_width=mask_width,
                                        seed=seed)
            return
        if self.mode == _delay.DelayMode.MSEQ:
            bits, steps = length, 1
            self._offset, self._mask = 1, None
        else:
            bits, steps = MASKED_LENGTH, MASKED_STEPS
            self._offset, self._mask = 0, np.uint32((1 << mask_width) - 1)
        self._states = _lfsr.states(bits, seed, block, steps=steps).astype(np.uint32)
        # The map of `block` pulses as two lookup tables of 16 bits each: the image of a state is
        # the XOR of the images of its set bits (the register is linear over GF(2)).
        columns = [int(_lfsr.states(bits, 1 << bit, 2, steps=steps * block)[1])
                   for bit in range(bits)]
        self._tables = np.zeros(((bits + 15) // 16, 1 << 16), dtype=np.uint32)
        for half, table in enumerate(self._tables):
            for bit in range(min(16, bits - 16 * half)):
                table[1 << bit:2 << bit] = table[:1 << bit] ^ np.uint32(columns[16 * half + bit])

    @property
    def table(self):
        """One whole period of a tabulated sequence from its start, or ``None``."""
        return self._table

    def _next_states(self):
        # The low and high 16 bits of each state, as strided views of the uint32 array
        halves = self._states.view(np.uint16)
        low, high = (0, 1) if sys.byteorder == "little" else (1, 0)
        result = np.take(self._tables[0], halves[low::2])
        if len(self._tables) > 1:
            result ^= np.take(self._tables[1], halves[high::2])
        self._states = result

    def take(self, count):
        """The next ``count`` delays, as ``numpy.int64``."""
        if self._table is not None:
            index = (self._position + np.arange(count, dtype=np.int64)) % len(self._table)
            self._position = (self._position + count) % len(self._table)
            return self._table[index]
        pieces = []
        while count > 0:
            if self._position == len(self._states):
                self._next_states()
                self._position = 0
            piece = self._states[self._position:self._position + count]
            self._position += len(piece)
            count -= len(piece)
            pieces.append(piece)
        states = np.concatenate(pieces) if pieces else np.zeros(0, dtype=np.uint32)
        return self._delays_of(states)

    def _delays_of(self, states):
        if self._mask is not None:
            return (states & self._mask).astype(np.int64)
        return states.astype(np.int64) - self._offset

    def block(self):
        """The delays from the current position to the end of the current block of register
        states (all of a block but the first time); the same sequence as :meth:`take`. Only for
        sequences that are not tabulated."""
        if self._position == len(self._states):
            self._next_states()
            self._position = 0
        states = self._states[self._position:]
        self._position = len(self._states)
        return self._delays_of(states)


class _Schedule:
    """Laser rising edges (TDC starts) of a delay core, in clock cycles, block by block."""

    def __init__(self, settings, block):
        self._settings = settings
        self._delays = DelayStream(settings.mode, length=settings.length,
                                   mask_width=settings.mask_width, seed=settings.seed)
        self._take = 0
        self._block = block
        self._pattern = None
        table = self._delays.table
        if table is not None:
            # A short sequence: the edges of whole sequence periods, computed once and shifted.
            delays = np.tile(table, max(1, -(-block // len(table))))
            self._pattern = self._edges(delays)
            self._length = self._take
            self._take = 0

    def _edges(self, delays):
        period, grid = self._settings.period, self._settings.grid
        if grid:
            fires = _scheduler.fire_cycles(delays, period, grid=True, start=self._take)
            self._take += period * len(delays)
            return fires + _scheduler.LATENCY
        # Interval mode, as fire_cycles: pulse k fires 1 + R[k] cycles after its take cycle
        # start + sum(T + R[i], i < k), that is at start + cumsum(T + R)[k] - T + 1.
        ends = np.cumsum(delays + period)
        edges = ends + (self._take - period + 1 + _scheduler.LATENCY)
        self._take += int(ends[-1]) if len(ends) else 0
        return edges

    def __call__(self):
        if self._pattern is not None:
            edges = self._pattern + self._take
            self._take += self._length
            return edges
        return self._edges(self._delays.block())


class _Buffer:
    """An increasing sequence read by global index, made block by block by ``blocks()`` or, when
    ``blocks`` is ``None``, fed from outside (then ``get`` returns what is known)."""

    def __init__(self, blocks):
        self._blocks = blocks
        self._data = np.zeros(0, dtype=np.int64)
        self._base = 0

    @property
    def end(self):
        """Index after the last value known."""
        return self._base + len(self._data)

    def feed(self, values):
        self._data = np.concatenate((self._data, values))

    def get(self, lo, hi):
        while self._base + len(self._data) < hi and self._blocks is not None:
            self._data = np.concatenate((self._data[lo - self._base:], self._blocks()))
            self._base = lo
        return self._data[lo - self._base:hi - self._base]

    def trim(self, lo):
        if lo > self._base:
            self._data = self._data[lo - self._base:]
            self._base = lo


class _Pulses:
    """Arrival times (pulse centres, LSBs) of one pulsed source, handed out in increasing order."""

    def __init__(self, buffer=None, *, scale=1.0, shift=0.0, step=None, guess=4096, trim=True):
        self._buffer = buffer
        self._trim = trim
        self._scale, self._shift, self._step = scale, shift, step
        self._next = 0
        self._guess = guess

    def until(self, limit):
        """Centres of the pulses not handed out yet that arrive before ``limit``."""
        if self._buffer is None:
            # Arithmetic train: centre of pulse j is shift + j * step.
            end = max(self._next, math.ceil((limit - self._shift) / self._step))
            centres = self._shift + np.arange(self._next, end, dtype=np.float64) * self._step
            self._next = end
            return centres
        count = self._guess
        while True:
            cycles = self._buffer.get(self._next, self._next + count)
            centres = cycles * self._scale + self._shift
            found = int(np.searchsorted(centres, limit, side="left"))
            if found < len(centres) or len(centres) < count:
                break                       # past the limit, or no more pulses known yet
            count *= 2
        self._next += found
        if self._trim:
            self._buffer.trim(self._next)
        return centres[:found]

    @property
    def next_index(self):
        return self._next


@dataclass
class Chunk:
    """What one :meth:`Simulation.step` produced.

    Attributes
    ----------
    first_pulse : int
        Index of its first laser cycle.
    start_cycles : numpy.ndarray
        TDC start (laser rising edge) of each of its cycles, in clock cycles.
    events : numpy.ndarray
        ``EVENT_DTYPE`` events, in time order.
    counts : numpy.ndarray
        ``(sources, len(COUNTERS))`` photon counters of the chunk.
    """

    first_pulse: int
    start_cycles: np.ndarray
    events: np.ndarray
    counts: np.ndarray

    @property
    def cycles(self):
        return len(self.start_cycles)


def _non_paralysable(times, dead, last):
    """Which photons (sorted ``times``) a non-paralysable detector detects; ``last`` is the time
    of the last detection before them."""
    count = len(times)
    if count == 0 or dead <= 0:
        return np.ones(count, dtype=bool)
    previous = np.empty(count)
    previous[0] = last
    previous[1:] = times[:-1]
    # A photon at least one dead time after the previous photon is detected whatever happened
    # before. The others sit in clusters behind such a photon and are resolved in order, one
    # position of all clusters at a time.
    detected = (times - previous) >= dead
    if detected.all():
        return detected
    heads = np.maximum.accumulate(np.where(detected, np.arange(count), -1))
    open_ = np.flatnonzero(~detected)
    head = heads[open_]
    clusters, cluster = np.unique(head, return_inverse=True)
    reference = np.where(clusters >= 0, times[np.maximum(clusters, 0)], last)
    position = open_ - head
    order = np.argsort(position, kind="stable")
    bounds = np.searchsorted(position[order], np.arange(1, position.max() + 2))
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        members = order[lo:hi]
        index = open_[members]
        owner = cluster[members]
        ok = times[index] - reference[owner] >= dead
        detected[index] = ok
        reference[owner[ok]] = times[index[ok]]
    return detected


def _cycles(values, what):
    values = np.asarray(values)
    if values.ndim != 1 or (len(values) and not np.issubdtype(values.dtype, np.integer)):
        raise ValueError(f"{what} must be a 1-D array of whole clock cycles")
    return values.astype(np.int64)


class Simulation:
    """The scene, laser cycle after laser cycle, in chunks.

    Parameters
    ----------
    scene : Scene
    seed : int or numpy.random.SeedSequence or None
        Seed of the photon statistics (the delay sequences have their own seeds in the settings).
    chunk_cycles : int
        Laser cycles per chunk: memory is proportional to it.
    external_starts : bool
        The victim's TDC starts do not come from the reference scheduler (``scene.victim``) but
        are given with :meth:`feed`, for instance as a simulated gateware emits them; a laser
        cycle is simulated once the start of the next one is known.
    external_aggressors : bool
        The aggressors' laser triggers are given with :meth:`feed_aggressor`: each aggressor is
        then a pulse ``offset_s + tof`` after each trigger edge, and its own period and delay
        settings are not used.
    """

    def __init__(self, scene, *, seed=None, chunk_cycles=1 << 16, external_starts=False,
                 external_aggressors=False):
        if not isinstance(scene, Scene):
            raise ValueError(f"Expected a Scene, not {scene!r}")
        if isinstance(chunk_cycles, bool) or not isinstance(chunk_cycles, (int, np.integer)) \
                or chunk_cycles < 1:
            raise ValueError(f"Chunk size must be a positive number of laser cycles, "
                             f"not {chunk_cycles!r}")
        self.scene = scene
        self.chunk_cycles = int(chunk_cycles)
        self._rng = np.random.default_rng(seed)
        lsb = scene.lsb_per_cycle
        self._lsb = lsb
        self._dead = scene.dead_time_s / TDC_LSB_S
        self._background = scene.background_hz * TDC_LSB_S
        jitter = scene.jitter_fwhm_s / FWHM_PER_SIGMA / TDC_LSB_S
        self.external_starts = bool(external_starts)
        self._starts = _Buffer(None if self.external_starts else
                               _Schedule(scene.victim, self.chunk_cycles + 1))
        # Pulsed sources: (pulses, mean detections, sigma in LSBs, margin in LSBs)
        self._pulsed = []
        sigma = math.hypot(scene.fwhm_s / FWHM_PER_SIGMA / TDC_LSB_S, jitter)
        # Fed from outside, the victim fires with some of the starts only (see `feed`).
        self._fired = _Buffer(None) if self.external_starts else self._starts
        self._signal = _Pulses(self._fired, scale=lsb, shift=scene.tof_s / TDC_LSB_S,
                               guess=self.chunk_cycles + 2, trim=self.external_starts)
        self._pulsed.append((self._signal,
                             scene.detections_per_pulse, sigma))
        self.external_aggressors = bool(external_aggressors)
        self._aggressor_edges = []
        self._last_edges = [np.zeros(0, dtype=np.int64) for _ in scene.aggressors]
        for aggressor in scene.aggressors:
            tof = scene.tof_s if aggressor.tof_s is None else aggressor.tof_s
            shift = (aggressor.offset_s + tof) / TDC_LSB_S
            if self.external_aggressors:
                edges = _Buffer(None)
                self._aggressor_edges.append(edges)
                pulses = _Pulses(edges, scale=lsb, shift=shift, guess=64)
            elif aggressor.has_delays:
                pulses = _Pulses(_Buffer(_Schedule(aggressor.settings(), self.chunk_cycles)),
                                 scale=lsb, shift=shift, guess=self.chunk_cycles + 2)
            else:
                pulses = _Pulses(shift=shift + (1 + _scheduler.LATENCY) * lsb,
                                 step=float(aggressor.period_cycles) * lsb)
            sigma = math.hypot(aggressor.fwhm_s / FWHM_PER_SIGMA / TDC_LSB_S, jitter)
            self._pulsed.append((pulses, aggressor.detections_per_pulse, sigma))
        self._sources = len(scene.sources)
        # Windows and dead times of consecutive pulses never meet when the shortest time between
        # two TDC starts is longer than both: a faster path that needs no per-cycle arrays.
        victim = scene.victim
        shortest = victim.period - (_delay.max_delay(victim.mode, length=victim.length,
                                                     mask_width=victim.mask_width)
                                    if victim.grid else 0)
        self._separated = shortest * lsb > TDC_CODES + self._dead and not self.external_starts
        self.pulse = 0
        self._previous_end = -math.inf
        self._last_detection = -math.inf
        self._carry_times = np.zeros(0)
        self._carry_sources = np.zeros(0, dtype=np.int8)
        #: Photon counters since the start, ``(sources, len(COUNTERS))``.
        self.counts = np.zeros((self._sources, len(COUNTERS)), dtype=np.int64)

    @property
    def next_start_cycle(self):
        """TDC start cycle of the next laser cycle to simulate (``None`` if not fed yet)."""
        known = self._starts.get(self.pulse, self.pulse + 1)
        return int(known[0]) if len(known) else None

    def feed(self, start_cycles, *, fired=True):
        """Give the next TDC starts, in clock cycles, with ``external_starts``: integers,
        increasing, after every start given before. With ``fired``, the victim laser fires with
        them (its echo follows); without, they only close the previous TDC window."""
        if not self.external_starts:
            raise ValueError("This simulation takes its TDC starts from the scheduler model; "
                             "create it with external_starts=True to feed them")
        values = _cycles(start_cycles, "TDC starts")
        previous = self._starts.get(self._starts.end - 1, self._starts.end)
        if np.any(np.diff(np.concatenate((previous, values))) <= 0):
            raise ValueError("TDC starts must increase strictly, also across calls to feed()")
        self._starts.feed(values)
        if fired:
            self._fired.feed(values)

    def feed_aggressor(self, index, edge_cycles):
        """Give the next rising edges of aggressor ``index``'s laser trigger, in clock cycles,
        with ``external_aggressors``: integers, increasing, after every edge given before. Give
        each edge before :meth:`step` simulates the laser cycles its photons fall in: photons of
        an edge given later are not simulated."""
        if not self.external_aggressors:
            raise ValueError("This simulation takes its aggressors from their settings; create "
                             "it with external_aggressors=True to feed their triggers")
        if not isinstance(index, (int, np.integer)) or not 0 <= index < len(self._aggressor_edges):
            raise ValueError(f"Aggressor index must be from 0 to "
                             f"{len(self._aggressor_edges) - 1}, not {index!r}")
        values = _cycles(edge_cycles, "Aggressor trigger edges")
        previous = self._last_edges[index]
        if np.any(np.diff(np.concatenate((previous, values))) <= 0):
            raise ValueError("Aggressor trigger edges must increase strictly, also across calls "
                             "to feed_aggressor()")
        self._aggressor_edges[index].feed(values)
        if len(values):
            self._last_edges[index] = values[-1:]

    def step(self, max_cycles=None, *, until_cycle=None):
        """Simulate the next laser cycles: at most ``max_cycles`` (default: one chunk), and only
        those whose TDC start is before clock cycle ``until_cycle``. Returns a :class:`Chunk`."""
        rng = self._rng
        max_cycles = self.chunk_cycles if max_cycles is None else int(max_cycles)
        cycles = self._starts.get(self.pulse, self.pulse + max_cycles + 1)
        count = max(min(max_cycles, len(cycles) - 1), 0)   # the next start must be known
        if until_cycle is not None:
            count = int(np.searchsorted(cycles[:count], until_cycle, side="left"))
        if count == 0:
            return Chunk(self.pulse, cycles[:0].copy(), np.zeros(0, dtype=EVENT_DTYPE),
                         np.zeros_like(self.counts))
        edges = cycles[:count + 1] * self._lsb
        starts = edges[:-1]
        if self._separated:
            # Every span is [start - dead, start + 2**13) and they never touch.
            boundary = edges[-1] - self._dead
        else:
            ends = np.minimum(starts + TDC_CODES, edges[1:])
            span_starts = np.maximum(starts - self._dead,
                                     np.concatenate(([self._previous_end], ends[:-1])))
            boundary = max(edges[-1] - self._dead, ends[-1])

        # Photons: carried over, from each pulsed source, and background in the spans
        times = [self._carry_times]
        sources = [self._carry_sources]
        for index, (pulses, mean, sigma) in enumerate(self._pulsed):
            index = index if index == 0 else index + 1
            centres = pulses.until(boundary + TRUNCATION_SIGMAS * sigma + 1.0)
            if mean == 0 or len(centres) == 0:
                continue
            number = rng.poisson(mean * len(centres))
            spread = np.clip(rng.standard_normal(number), -TRUNCATION_SIGMAS, TRUNCATION_SIGMAS)
            times.append(centres[rng.integers(0, len(centres), number)] + sigma * spread)
            sources.append(np.full(number, index, dtype=np.int8))
        if self._background > 0:
            # A Poisson process on each span: drawn on spans all as long as the longest, then
            # thinned to each span's true length.
            if self._separated:
                longest = TDC_CODES + self._dead
            else:
                lengths = ends - span_starts
                longest = float(lengths.max())
            number = rng.poisson(self._background * longest * count)
            span = rng.integers(0, count, number)
            offset = rng.uniform(0.0, longest, number)
            if self._separated:
                times.append(starts[span] + (offset - self._dead))
            else:
                inside = offset < lengths[span]
                times.append(span_starts[span[inside]] + offset[inside])
                number = int(inside.sum())
            sources.append(np.full(number, 1, dtype=np.int8))
        times = np.concatenate(times)
        sources = np.concatenate(sources)
        later = times >= boundary
        if later.any():
            self._carry_times, self._carry_sources = times[later], sources[later]
            now = ~later
            times, sources = times[now], sources[now]
        else:
            self._carry_times, self._carry_sources = times[:0], sources[:0]
        order = np.argsort(times)
        times = times[order]
        sources = sources[order]

        # Which span each photon is in: the TDC window of `span`, or the dead time before it
        if self._separated:
            span = np.searchsorted(starts, times + self._dead, side="right") - 1
            offset = times - starts[np.maximum(span, 0)]
            in_span = (span >= 0) & (offset < TDC_CODES)
            in_window = in_span & (offset >= 0)
        else:
            span = np.searchsorted(span_starts, times, side="right") - 1
            clipped = np.maximum(span, 0)
            in_span = (span >= 0) & (times < ends[clipped])
            in_window = in_span & (times >= starts[clipped])

        # Detection: which span, dead time, single-hit TDC
        counts = np.zeros_like(self.counts)
        counts[:, _GENERATED] = np.bincount(sources, minlength=self._sources)
        span_times = times[in_span]
        detected = _non_paralysable(span_times, self._dead, self._last_detection)
        if detected.any():
            self._last_detection = float(span_times[detected][-1])
        window = in_window[in_span]
        candidate = window & detected
        picked = np.flatnonzero(in_span)[candidate]
        cycle = span[picked]
        if self.scene.keep == "last":
            keep = np.ones(len(cycle), dtype=bool)
            keep[:-1] = cycle[1:] != cycle[:-1]
        else:
            keep = np.ones(len(cycle), dtype=bool)
            keep[1:] = cycle[1:] != cycle[:-1]
        recorded = picked[keep]
        counts[:, _OUTSIDE] = np.bincount(sources[~in_window], minlength=self._sources)
        counts[:, _DEAD] = np.bincount(sources[np.flatnonzero(in_span)[window & ~detected]],
                                       minlength=self._sources)
        counts[:, _OVERWRITTEN] = np.bincount(sources[picked[~keep]], minlength=self._sources)
        counts[:, _RECORDED] = np.bincount(sources[recorded], minlength=self._sources)

        events = np.zeros(len(recorded), dtype=EVENT_DTYPE)
        cycle = span[recorded]
        stamps = np.floor(times[recorded] - starts[cycle]).astype(np.int64)
        events["timestamp"] = np.minimum(stamps, TDC_CODES - 1)
        events["address"] = self.scene.address
        events["pulse"] = (self.pulse + cycle) & ((1 << PULSE_BITS) - 1)

        chunk = Chunk(self.pulse, cycles[:count].copy(), events, counts)
        self.pulse += count
        self._starts.trim(self.pulse if self.external_starts else
                          min(self.pulse, self._signal.next_index))
        self._previous_end = float(starts[-1] + TDC_CODES if self._separated else ends[-1])
        self.counts += counts
        return chunk

    def chunks(self, cycles):
        """Chunks covering the next ``cycles`` laser cycles (fewer if the TDC starts fed so far
        run out first)."""
        remaining = int(cycles)
        while remaining > 0:
            chunk = self.step(min(remaining, self.chunk_cycles))
            if chunk.cycles == 0:
                return
            remaining -= chunk.cycles
            yield chunk


def histogram(events):
    """Histogram of the timestamps of ``events``: ``TDC_CODES`` bins, ``numpy.int64``."""
    return np.bincount(np.asarray(events["timestamp"], dtype=np.int64), minlength=TDC_CODES)


@dataclass
class Acquisitions:
    """Consecutive acquisitions of one continuous run.

    Attributes
    ----------
    histograms : numpy.ndarray
        ``(acquisitions, TDC_CODES)`` counts per TDC code.
    counts : numpy.ndarray
        ``(acquisitions, sources, len(COUNTERS))`` photon counters.
    cycles : numpy.ndarray
        Laser cycles in each acquisition.
    sources : tuple of str
    t_int_cycles : int
        Integration time in clock cycles.
    """

    histograms: np.ndarray
    counts: np.ndarray
    cycles: np.ndarray
    sources: tuple
    t_int_cycles: int
    events: list = field(default_factory=list)


def acquire(scene, t_int_s, acquisitions, *, seed=None, chunk_cycles=1 << 16, keep_events=False,
            progress=None):
    """Run the scene for ``acquisitions`` consecutive integration times of ``t_int_s`` each.

    Acquisition ``a`` holds the laser cycles whose TDC start falls in clock cycles
    ``[a * T, (a + 1) * T)``, ``T = round(t_int_s * clock_hz)``, as the histogram engine
    integrates over a time set in clock cycles; the delay sequences run on across acquisitions.
    ``progress``, if given, is called with the number of laser cycles after each chunk.
    """
    _check_number(t_int_s, "Integration time (s)", positive=True)
    if isinstance(acquisitions, bool) or not isinstance(acquisitions, (int, np.integer)) \
            or acquisitions < 1:
        raise ValueError(f"Number of acquisitions must be a positive integer, "
                         f"not {acquisitions!r}")
    t_int_cycles = int(round(t_int_s * scene.clock_hz))
    if t_int_cycles < 1:
        raise ValueError(f"Integration time {t_int_s!r} s is shorter than one clock cycle")
    simulation = Simulation(scene, seed=seed, chunk_cycles=chunk_cycles)
    histograms = np.zeros((acquisitions, TDC_CODES), dtype=np.int64)
    counts = np.zeros((acquisitions, len(scene.sources), len(COUNTERS)), dtype=np.int64)
    cycles = np.zeros(acquisitions, dtype=np.int64)
    kept = []
    for index in range(acquisitions):
        end = (index + 1) * t_int_cycles
        pieces = []
        while simulation.next_start_cycle < end:
            chunk = simulation.step(until_cycle=end)
            histograms[index] += histogram(chunk.events)
            counts[index] += chunk.counts
            cycles[index] += chunk.cycles
            if keep_events:
                pieces.append(chunk.events)
            if progress is not None:
                progress(chunk.cycles)
        if keep_events:
            kept.append(np.concatenate(pieces) if pieces else np.zeros(0, dtype=EVENT_DTYPE))
    return Acquisitions(histograms, counts, cycles, scene.sources, t_int_cycles, kept)
