"""Model of the fine TDC (:mod:`fliss.hdl.finetdc`): the delay line's physics, and the bit-exact
encoder, coarse count and table lookup of the gateware.

The line (:class:`Line`): tap ``j`` reads 1 at a clock edge once the hit's edge has passed it,
that is when the time ``tau`` from the hit to the edge exceeds its threshold
``E_j = offset + d_0 + … + d_j``. The tap delays ``d`` are the timing model's (:data:`TAP_S`)
plus Gaussian variation of ``sigma_s``, and ``tile_extra_s`` more at every ``tile_taps``-th tap
(a hop between logic tiles); all drawn once from ``seed``, as one chip is made once. At each
sample, a tap within ``metastable_s / 2`` of its threshold reads a random bit, and with
probability ``bubble_probability`` the two taps at the edge read swapped (a bubble: clock skew
between their flip-flops). The ones count ignores where the ones are, so bubbles leave the code
as it is.

The gateware (:func:`captures`): the first non-zero sample after an all-zero one is a hit; its
ones count indexes the calibration table; the capture's timestamp is the whole cycles since the
TDC start in table units minus the table's fine time, at the selected LSB.
"""

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ...hdl.event import PULSE_BITS, TIMESTAMP_BITS
from ...hdl.finetdc import TAPS, TAP_S, LATENCY, cycle_units, elapsed_limit


__all__ = ["Line", "captures"]


@dataclass(frozen=True)
class Line:
    """A delay line of ``taps`` taps (see the module's description for the parameters)."""
    taps: int = TAPS
    tap_s: float = TAP_S
    sigma_s: float = 5e-12
    tile_taps: int = 8
    tile_extra_s: float = 0.0
    offset_s: float = 0.4e-9
    metastable_s: float = 2e-12
    bubble_probability: float = 0.02
    seed: int = 1

    def __post_init__(self):
        if isinstance(self.taps, bool) or not isinstance(self.taps, int) or self.taps < 2:
            raise ValueError(f"A delay line needs at least 2 taps, not {self.taps!r}")
        for name in ("tap_s", "sigma_s", "tile_extra_s", "offset_s", "metastable_s"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must not be negative, not {getattr(self, name)!r}")
        if not 0 <= self.bubble_probability <= 1:
            raise ValueError(f"Bubble probability must be from 0 to 1, "
                             f"not {self.bubble_probability!r}")

    @cached_property
    def delays_s(self):
        """Delay of each tap, in seconds (at least 1 ps)."""
        rng = np.random.default_rng(self.seed)
        delays = rng.normal(self.tap_s, self.sigma_s, self.taps)
        delays[self.tile_taps - 1::self.tile_taps] += self.tile_extra_s
        return np.maximum(delays, 1e-12)

    @cached_property
    def thresholds_s(self):
        """Time from the hit to the clock edge above which each tap reads 1."""
        return self.offset_s + np.cumsum(self.delays_s)

    def codes(self, tau_s, rng):
        """Ones count of the samples of hits ``tau_s`` before the clock edge (vectorised: the
        same statistics as the popcount of :meth:`samples`)."""
        tau = np.asarray(tau_s, dtype=np.float64)
        edges = self.thresholds_s
        base = np.searchsorted(edges, tau, side="left")     # thresholds below tau
        code = base.copy()
        half = self.metastable_s / 2
        for step in (-2, -1, 0, 1):
            tap = np.clip(base + step, 0, self.taps - 1)
            near = (np.abs(tau - edges[tap]) < half) & (base + step == tap)
            settled = tau > edges[tap]
            random = rng.random(tau.shape) < 0.5
            code = code + np.where(near, random.astype(np.int64) - settled, 0)
        return code

    def samples(self, tau_s, rng, *, width_s=np.inf):
        """The sampled taps, ``(len(tau_s), taps)`` booleans, for hits ``tau_s`` before the
        clock edge, each high for ``width_s`` (its fall has passed the taps below
        ``tau_s - width_s``)."""
        tau = np.asarray(tau_s, dtype=np.float64)[:, None]
        edges = self.thresholds_s[None, :]
        bits = (tau > edges) & ~(tau - width_s > edges)
        half = self.metastable_s / 2
        near = (np.abs(tau - edges) < half) | (np.abs(tau - width_s - edges) < half)
        bits = np.where(near, rng.random(bits.shape) < 0.5, bits)
        # A bubble at the rising edge: the last one and the first zero swapped
        front = np.searchsorted(self.thresholds_s, tau[:, 0], side="left")
        rows = np.flatnonzero((rng.random(len(bits)) < self.bubble_probability) &
                              (front > 0) & (front < self.taps))
        last = front[rows] - 1
        bits[rows, last], bits[rows, last + 1] = bits[rows, last + 1], bits[rows, last]
        return bits


def captures(codes, starts, table, *, clock_hz, lsb_select=0, raw=False, pulse_index=None):
    """The captures of :class:`~fliss.hdl.finetdc.tdc.FineTdc`, bit-exact.

    Parameters
    ----------
    codes : array_like of int
        Ones count of the line's first-stage sample in each cycle.
    starts : array_like of bool
        ``tdc_start`` in each cycle.
    table : array_like of int
        The calibration table (raw code -> fine time in table units).
    lsb_select : int
        ``fine_lsb``: timestamps in LSBs of ``50 ps / 2**lsb_select``.
    raw : bool
        Raw mode: the timestamp is the raw code.
    pulse_index : array_like of int or None
        ``pulse_index`` in each cycle (``None``: all zero).

    Returns
    -------
    list of dict
        One per hit: ``cycle`` (in which ``captures.valid`` is high), ``timestamp``,
        ``overflow``, ``pulse``.
    """
    codes = np.asarray(codes, dtype=np.int64)
    starts = np.asarray(starts, dtype=bool)
    units = cycle_units(clock_hz)
    limit = elapsed_limit(clock_hz)
    found = []
    elapsed = None      # whole cycles since the last start, None: never or past the limit
    previous = 0
    for cycle, code in enumerate(codes):
        if starts[cycle]:
            elapsed = 0
        elif elapsed is not None:
            elapsed = elapsed + 1 if elapsed < limit else None
        if code and not previous:
            pulse = 0 if pulse_index is None else int(pulse_index[cycle])
            fine = int(table[code])
            if raw:
                timestamp, overflow = int(code), False
            elif elapsed is None or elapsed * units < fine:
                timestamp, overflow = 0, True
            else:
                timestamp = (elapsed * units - fine) >> (2 - lsb_select)
                overflow = timestamp >> TIMESTAMP_BITS != 0
                timestamp &= (1 << TIMESTAMP_BITS) - 1
            found.append({"cycle": cycle + LATENCY, "timestamp": timestamp,
                          "overflow": bool(overflow),
                          "pulse": (pulse - 1) % (1 << PULSE_BITS)})
        previous = code
    return found
