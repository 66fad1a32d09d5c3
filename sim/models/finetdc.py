"""Model of the fine TDC (:mod:`fliss.hdl.finetdc`): the delay lines' physics, and the bit-exact
encoder, coarse count and table lookup of the gateware.

The lines (:class:`Line`): ``lines`` delay lines of ``taps`` taps each, fed by the one hit. Tap
``j`` of a line reads 1 at a clock edge once the hit's edge has passed it, that is when the time
``tau`` from the hit to the edge exceeds its threshold ``E_j = offset + d_0 + … + d_j``. The tap
delays ``d`` are ``tap_s`` plus Gaussian variation of ``sigma_s``, and ``hop_s`` more at every
``hop_taps``-th tap (nextpnr's routed ECP5 line: 8.4 ps within a ``CCU2C``, 54.1 ps more from
one cell to the next, every second tap); each line after the first starts a uniform random time
up to ``phase_s`` after the first (the routes from the hit to the chains differ); all drawn once
from ``seed``, as one chip is made once, and all times multiplied by ``scale`` (the same chip at
another temperature). At each sample, a tap within ``metastable_s / 2`` of its threshold reads a
random bit, and with probability ``bubble_probability`` the two taps at a line's edge read
swapped (a bubble: clock skew between their flip-flops), in each line on its own. The raw code
is the ones count of all the lines' taps: where the ones are does not matter, so bubbles leave
it as it is, and it is the number of the lines' thresholds, merged, below ``tau``.

The gateware (:func:`captures`): the first non-zero sample after an all-zero one is a hit; its
ones count indexes the calibration table; the capture's timestamp is the whole cycles since the
TDC start in table units minus the table's fine time, at the selected LSB.
"""

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ...hdl.event import PULSE_BITS, TIMESTAMP_BITS
from ...hdl.finetdc import LINE_TAPS, LINES, LATENCY
from ...hdl.clock import cycle_units, elapsed_limit


__all__ = ["Line", "captures"]


@dataclass(frozen=True)
class Line:
    """``lines`` delay lines of ``taps`` taps each (see the module's description for the
    parameters). The defaults: the gateware's lines (:data:`~fliss.hdl.finetdc.LINES` of
    :data:`~fliss.hdl.finetdc.LINE_TAPS`) with nextpnr's tap delays and 5 ps of variation."""
    taps: int = LINE_TAPS
    lines: int = LINES
    tap_s: float = 8.4e-12
    sigma_s: float = 5e-12
    hop_taps: int = 2
    hop_s: float = 54.1e-12
    phase_s: float = 71e-12
    offset_s: float = 0.4e-9
    metastable_s: float = 2e-12
    bubble_probability: float = 0.02
    scale: float = 1.0
    seed: int = 1

    def __post_init__(self):
        for name, least in (("taps", 2), ("lines", 1), ("hop_taps", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ValueError(f"{name} must be a whole number of at least {least}, "
                                 f"not {value!r}")
        for name in ("tap_s", "sigma_s", "hop_s", "phase_s", "offset_s", "metastable_s"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must not be negative, not {getattr(self, name)!r}")
        if not self.scale > 0:
            raise ValueError(f"scale must be positive, not {self.scale!r}")
        if not 0 <= self.bubble_probability <= 1:
            raise ValueError(f"Bubble probability must be from 0 to 1, "
                             f"not {self.bubble_probability!r}")

    @property
    def total_taps(self):
        """Taps of all the lines: raw codes are 0 to ``total_taps``."""
        return self.lines * self.taps

    @cached_property
    def delays_s(self):
        """Delay of each tap, ``(lines, taps)``, in seconds (at least 1 ps)."""
        rng = np.random.default_rng(self.seed)
        delays = rng.normal(self.tap_s, self.sigma_s, (self.lines, self.taps))
        delays[:, self.hop_taps - 1::self.hop_taps] += self.hop_s
        return np.maximum(delays, 1e-12) * self.scale

    @cached_property
    def line_thresholds_s(self):
        """Time from the hit to the clock edge above which each tap reads 1, ``(lines,
        taps)``."""
        starts = np.full(self.lines, self.offset_s)
        if self.lines > 1:
            rng = np.random.default_rng([self.seed, 1])
            starts[1:] += rng.uniform(0, self.phase_s, self.lines - 1)
        return starts[:, None] * self.scale + np.cumsum(self.delays_s, axis=1)

    @cached_property
    def thresholds_s(self):
        """All the lines' thresholds, merged in order: code ``c`` is a hit between thresholds
        ``c - 1`` and ``c``."""
        return np.sort(self.line_thresholds_s, axis=None)

    @property
    def mean_code_s(self):
        """Mean width of a code, over the lines' thresholds merged."""
        edges = self.thresholds_s
        return float(edges[-1] - edges[0]) / (len(edges) - 1)

    def codes(self, tau_s, rng):
        """Ones count of the samples of hits ``tau_s`` before the clock edge (vectorised: the
        same statistics as the popcount of :meth:`samples`)."""
        tau = np.asarray(tau_s, dtype=np.float64)
        edges = self.thresholds_s
        base = np.searchsorted(edges, tau, side="left")     # thresholds below tau
        code = base.copy()
        half = self.metastable_s / 2
        for step in (-2, -1, 0, 1):
            tap = np.clip(base + step, 0, len(edges) - 1)
            near = (np.abs(tau - edges[tap]) < half) & (base + step == tap)
            settled = tau > edges[tap]
            random = rng.random(tau.shape) < 0.5
            code = code + np.where(near, random.astype(np.int64) - settled, 0)
        return code

    def samples(self, tau_s, rng, *, width_s=np.inf):
        """The sampled taps, ``(len(tau_s), lines * taps)`` booleans (line ``k``'s tap ``j`` in
        column ``k * taps + j``, as the gateware's ``sampled``), for hits ``tau_s`` before the
        clock edge, each high for ``width_s`` (its fall has passed the taps below
        ``tau_s - width_s``)."""
        tau = np.asarray(tau_s, dtype=np.float64)
        return np.concatenate([self._line_samples(edges, tau, rng, width_s)
                               for edges in self.line_thresholds_s], axis=1)

    def _line_samples(self, thresholds, tau, rng, width_s):
        # One line's sampled taps
        edges = thresholds[None, :]
        tau = tau[:, None]
        bits = (tau > edges) & ~(tau - width_s > edges)
        half = self.metastable_s / 2
        near = (np.abs(tau - edges) < half) | (np.abs(tau - width_s - edges) < half)
        bits = np.where(near, rng.random(bits.shape) < 0.5, bits)
        # A bubble at the rising edge: the last one and the first zero swapped
        front = np.searchsorted(thresholds, tau[:, 0], side="left")
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
        Ones count of the lines' first-stage sample in each cycle.
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
