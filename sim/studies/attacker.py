"""An attacker that predicts a FLISS victim's laser pulses from their emission times.

The attacker sees what a real adversary can measure: the times at which the victim's laser
emits, with timing jitter, some pulses missed (:class:`Observer`). It knows the public design:
the clock, the nominal period ``T``, the scheduler modes (interval: pulse ``k + 1`` fires
``T + R[k + 1]`` cycles after pulse ``k``; grid: pulse ``k`` fires at ``k T + R[k]`` plus a
phase) and the polynomial table; not the seed, key or registers.

:class:`Attacker` rounds the observed times to whole clock cycles and reads delays from them:
``R = interval - T`` in interval mode (a missed pulse makes an interval of two frames, read as
one: the window holding it fails its checks and the search goes on after it), the offset from
the grid in grid mode (one reading per candidate phase, the phase being unknown). It then tries
every hypothesis of :mod:`fliss.sim.studies.generators` on every window of consecutive pulses.

Lock rule: a hypothesis locks when the state it solved from the fewest pulses that determine it
(or the recurrence Berlekamp–Massey found, from at least twice its length) predicts the next
``V`` pulses exactly, ``V`` being at least 4 pulses and at least ``verify_bits`` (48) predicted
bits: a wrong hypothesis passes by chance with probability at most ``2**-48`` per window. Once
locked, the attacker follows its predictions and checks each later observation against them
(allowing for missed pulses: an observation may match any later predicted pulse); the first
observation no prediction explains drops the lock and the search starts again from it.
"""

import math
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from ...hdl.clock import DEFAULT_CLOCK_HZ
from .generators import KnownTaps, hypotheses
from ..scene.checks import check_number


__all__ = ["Observer", "Lock", "AttackResult", "Attacker"]


@dataclass(frozen=True)
class Observer:
    """What the attacker's detector records of the victim's laser.

    Parameters
    ----------
    clock_hz : float
        The victim's clock (the start cycles are counted in it).
    jitter_s : float
        RMS timing jitter of each recorded emission time.
    missed : float
        Fraction of the victim's pulses not recorded, from 0 to below 1.
    seed : int or None
        Seed of the jitter and the misses.
    """

    clock_hz: float = DEFAULT_CLOCK_HZ
    jitter_s: float = 100e-12
    missed: float = 0.0
    seed: object = None

    def __post_init__(self):
        check_number(self.clock_hz, "Clock frequency (Hz)", positive=True)
        check_number(self.jitter_s, "Observer jitter (s)")
        check_number(self.missed, "Missed fraction")
        if not self.missed < 1:
            raise ValueError(f"Missed fraction must be below 1, not {self.missed!r}")

    def observe(self, start_cycles):
        """Times (s) of the recorded emissions and the index of the victim pulse of each."""
        starts = np.asarray(start_cycles, dtype=np.int64)
        rng = np.random.default_rng(self.seed)
        seen = np.flatnonzero(rng.random(len(starts)) >= self.missed)
        times = starts[seen] / self.clock_hz + rng.normal(0.0, self.jitter_s, len(seen)) \
            if self.jitter_s > 0 else starts[seen] / self.clock_hz
        return times, seen


@dataclass(frozen=True)
class Lock:
    """One period during which the attacker's predictions held.

    Attributes
    ----------
    observation : int
        Index of the observation at which the lock was declared.
    lost : int or None
        Index of the first observation the predictions did not explain, or ``None``.
    model : str
        The hypothesis that locked.
    base : int
        Index of the observation from which the predictions run (``predicted[0]`` is its
        victim pulse's delay).
    predicted : numpy.ndarray
        Predicted delays of the victim's pulses from the base pulse on, as far as the run went.
    """

    observation: int
    lost: object
    model: str
    base: int
    predicted: np.ndarray = field(repr=False)


@dataclass
class AttackResult:
    """What :meth:`Attacker.attack` found.

    Attributes
    ----------
    observations : int
        Emission times given.
    locks : list of Lock
    edges : numpy.ndarray
        The attacker's laser triggers, in the victim's clock cycles: at the victim's predicted
        TDC starts while locked, at the victim's measured effective PRF otherwise.
    prf_period_cycles : float
        Period of the unlocked firing: the mean observed interval.
    """

    observations: int
    locks: list
    edges: np.ndarray
    prf_period_cycles: float

    @property
    def locked_after(self):
        """Observed pulses until the first lock (the lock's own included), or ``None``."""
        return self.locks[0].observation + 1 if self.locks else None

    @property
    def model(self):
        return self.locks[0].model if self.locks else None


class Attacker:
    """The attacker: recovers the delays, then the generator, predicts and fires.

    Parameters
    ----------
    period : int
        The victim's nominal period ``T`` in clock cycles (public).
    grid : bool
        The victim's scheduler runs in grid mode.
    clock_hz : float
    known_taps, unknown_taps : bool
        Which hypotheses to try (see :func:`fliss.sim.studies.generators.hypotheses`).
    verify_bits : int
        Predicted bits that must hold before a lock.
    prf_pulses : int
        Observed pulses from which the unlocked firing period is measured; the attacker starts
        firing at that observation.
    jitter_s : float
        RMS jitter of its own emission times: once locked, an observation within five
        standard deviations of an interval (rounded down to whole cycles; 0 at 100 ps) of a
        predicted pulse matches it.
    """

    def __init__(self, period, *, grid=False, clock_hz=DEFAULT_CLOCK_HZ, known_taps=True,
                 unknown_taps=True, verify_bits=48, prf_pulses=16, jitter_s=100e-12):
        if isinstance(period, bool) or not isinstance(period, (int, np.integer)) or period < 2:
            raise ValueError(f"Period must be a whole number of at least 2 clock cycles, "
                             f"not {period!r}")
        check_number(clock_hz, "Clock frequency (Hz)", positive=True)
        if isinstance(verify_bits, bool) or not isinstance(verify_bits, (int, np.integer)) \
                or verify_bits < 1:
            raise ValueError(f"Verified bits must be a positive integer, not {verify_bits!r}")
        if isinstance(prf_pulses, bool) or not isinstance(prf_pulses, (int, np.integer)) \
                or prf_pulses < 2:
            raise ValueError(f"PRF pulses must be an integer of at least 2, not {prf_pulses!r}")
        self.period, self.grid, self.clock_hz = int(period), bool(grid), clock_hz
        self.prf_pulses = int(prf_pulses)
        check_number(jitter_s, "Attacker jitter (s)")
        self.tolerance = int(math.floor(5 * math.sqrt(2) * jitter_s * clock_hz))
        self.hypotheses = hypotheses(known_taps=known_taps, unknown_taps=unknown_taps,
                                     verify_bits=int(verify_bits))

    # Readings: (victim pulse index, delay, linked) of each observation

    def _readings(self, cycles):
        """Delay readings of observations given as cycles from the first; one per phase."""
        period = self.period
        if not self.grid:
            delays = np.empty(len(cycles), dtype=np.int64)
            delays[0] = -2                      # the first pulse's delay is not observable
            delays[1:] = np.diff(cycles) - period
            linked = np.ones(len(cycles), dtype=bool)
            linked[0] = False
            return [(np.arange(len(cycles)), delays, linked)]
        readings = []
        for phase in range(period):
            shifted = cycles + phase
            index = shifted // period
            linked = np.concatenate(([False], np.diff(index) == 1))
            readings.append((index, shifted % period, linked))
        return readings

    def _frames(self, base_delay, predicted):
        """Fire cycle of each predicted pulse after the base pulse, relative to the base."""
        if self.grid:
            steps = np.arange(1, len(predicted) + 1, dtype=np.int64) * self.period
            return steps + predicted - base_delay
        return np.cumsum(predicted + self.period)

    def _search(self, cycles):
        """The earliest lock in these observations: ``(lock index, base index, hypothesis,
        found, reading)`` or ``None``."""
        best = None
        readings = self._readings(cycles)
        for hypothesis in self.hypotheses:
            if not isinstance(hypothesis, KnownTaps):
                continue
            for reading in readings:
                _, delays, linked = reading
                found = hypothesis.first_lock(delays, linked)
                if found is None:
                    continue
                lock, first, state = found
                if best is None or lock < best[0]:
                    best = (lock, first, hypothesis, state, reading)
        for hypothesis in self.hypotheses:
            if isinstance(hypothesis, KnownTaps):
                continue
            for reading in self._bm_readings(readings):
                _, delays, linked = reading
                found = hypothesis.first_lock(delays, linked,
                                              stop=None if best is None else best[0])
                if found is not None and (best is None or found[0] < best[0]):
                    best = (found[0], found[0], hypothesis, found[1], reading)
        return best

    def _bm_readings(self, readings):
        # Berlekamp-Massey runs once a reading. In grid mode, only on the phase that puts the
        # largest circular gap between the first offsets just below delay 0: a source's delays
        # fill an arc of the period shorter than the period.
        if len(readings) == 1:
            return readings
        offsets = np.unique(readings[0][1][:256])
        gaps = np.diff(np.concatenate((offsets, offsets[:1] + self.period)))
        start = offsets[(int(np.argmax(gaps)) + 1) % len(offsets)]
        return [readings[int(-start) % self.period]]

    def _predict(self, hypothesis, found, delays, base, count):
        if isinstance(hypothesis, KnownTaps):
            return hypothesis.predict(found, count + 1)
        return np.concatenate(([delays[base]], hypothesis.predict(found, count)))

    def _track(self, cycles, base, lock, predicted_of):
        """Follow predictions from the lock; returns (lost observation or None, predicted
        delays from the base pulse, relative frames)."""
        rest = cycles[lock + 1:] - cycles[base]
        horizon = int(rest[-1]) if len(rest) else 0
        count = max(64, 2 * (lock - base + 2))
        while True:
            predicted = predicted_of(count)
            frames = np.concatenate(([0], self._frames(predicted[0], predicted[1:])))
            if frames[-1] >= horizon or count > 4 * (horizon // self.period + 2):
                break
            count *= 4
        position = np.clip(np.searchsorted(frames, rest), 1, len(frames) - 1)
        nearest = np.minimum(np.abs(frames[position] - rest), np.abs(frames[position - 1] - rest))
        matched = nearest <= self.tolerance
        # A lock already checks the pulses between base and lock; later ones must match too.
        wrong = np.flatnonzero(~matched)
        lost = None if len(wrong) == 0 else lock + 1 + int(wrong[0])
        return lost, predicted, frames

    def attack(self, times_s):
        """Run the attack on the emission times (s) the observer recorded; an
        :class:`AttackResult`."""
        times = np.asarray(times_s, dtype=float)
        if times.ndim != 1 or len(times) < 2 or not np.all(np.isfinite(times)):
            raise ValueError("The attacker needs at least two finite emission times")
        cycles = np.rint(times * self.clock_hz).astype(np.int64)
        if np.any(np.diff(cycles) <= 0):
            raise ValueError("Emission times must increase by at least one clock cycle")
        locks, spans = [], []
        position = 0
        while len(cycles) - position >= 2:
            # Search a prefix first, then longer ones: a lock comes early or not at all.
            span = 4096
            while True:
                found = self._search(cycles[position:position + span] - cycles[position])
                if found is not None or position + span >= len(cycles):
                    break
                span *= 8
            if found is None:
                break
            lock, base, hypothesis, state, reading = found
            lock, base = lock + position, base + position
            lost, predicted, frames = self._track(
                cycles, base, lock,
                partial(self._predict, hypothesis, state, reading[1], base - position))
            locks.append(Lock(lock, lost, hypothesis.name, base, predicted))
            end = cycles[lost] if lost is not None else cycles[-1] + 1
            starts = cycles[base] + frames
            starts = starts[(starts > cycles[lock]) & (starts < end)]
            spans.append((cycles[lock], end, starts))
            if lost is None:
                break
            position = lost
        return AttackResult(len(cycles), locks, *self._edges(cycles, spans))

    def _edges(self, cycles, spans):
        """The attacker's triggers: predictions while locked, the PRF train otherwise."""
        first = min(self.prf_pulses, len(cycles)) - 1
        period = float(cycles[first] - cycles[0]) / first
        begin = cycles[first]
        stop = cycles[-1] + 1
        count = int((stop - cycles[0]) / period) + 2
        train = cycles[0] + np.rint(np.arange(count) * period).astype(np.int64)
        keep = (train >= begin) & (train < stop)
        for lock_cycle, end, _ in spans:
            keep &= ~((train > lock_cycle) & (train < end))
        pieces = [train[keep]] + [starts for _, _, starts in spans]
        edges = np.unique(np.concatenate(pieces))
        return edges, period
