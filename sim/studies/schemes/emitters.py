"""When each camera's laser fires under each scheme, in the victim's time.

Every time is in TDC LSBs (50 ps) from the start of the victim's frame, as ``float64``. A
camera runs on its own oscillator: a time it sets in its own clock cycles is shorter by
``1 + ppm 1e-6`` in the victim's time, and its first pulse comes ``phase`` after ``start``.

* ``none``: a fixed period ``T``.
* ``hopping``: the period changes every ``dwell`` pulses to one of ``periods`` values
  ``T, T + step, ..., T + (periods - 1) step``, drawn uniformly and independently per dwell
  (the first dwell is cut at a uniform point, so the dwells of two cameras are not aligned).
* ``fliss``: the gateware's delay sequences (:class:`fliss.sim.scene.pulses.EdgeSchedule`,
  the reference scheduler, interval mode): pulse ``k`` after ``T + R[k]``.
* ``code``: a burst every ``T``, of ``chips`` pulses at the camera's code, chip ``j`` at
  ``slots[j] slot_cycles`` cycles after the burst's start; the code is a random Golomb ruler
  (:func:`golomb_code`: every difference of two chip positions occurs once, so the code's
  autocorrelation away from 0 is at most 1 chip).
"""

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ....hdl.clock import DEFAULT_CLOCK_HZ
from ....hdl.event import TDC_LSB_S
from ...models import delay as _delay
from ...models import scheduler as _scheduler
from ...scene.pulses import EdgeSchedule


__all__ = ["LSB_PER_CYCLE", "EMISSIONS", "Camera", "golomb_code", "mean_period_cycles",
           "is_golomb"]


#: TDC LSBs per clock cycle (250 at 80 MHz and 50 ps).
LSB_PER_CYCLE = 1.0 / (DEFAULT_CLOCK_HZ * TDC_LSB_S)

#: How a camera's laser is scheduled (see the module).
EMISSIONS = ("none", "hopping", "fliss", "code")


def is_golomb(slots):
    """Whether every difference of two of ``slots`` (distinct integers) occurs once."""
    slots = sorted(int(s) for s in slots)
    differences = [b - a for i, a in enumerate(slots) for b in slots[i + 1:]]
    return len(set(differences)) == len(differences) and len(set(slots)) == len(slots)


def golomb_code(rng, chips, slots):
    """A random code of ``chips`` positions among ``0 … slots - 1`` (position 0 always used)
    whose differences are all distinct (a Golomb ruler), drawn by rejection; ``ValueError`` if
    none exists in ``slots`` (a ruler of ``m`` marks needs a length of at least
    ``m (m - 1) / 2``)."""
    if chips * (chips - 1) // 2 > slots - 1:
        raise ValueError(f"{chips} chips need at least {chips * (chips - 1) // 2 + 1} slots "
                         f"for distinct differences, not {slots}")
    for _ in range(10000):
        rest = np.sort(rng.choice(np.arange(1, slots), chips - 1, replace=False))
        code = np.concatenate(([0], rest)).astype(np.int64)
        if is_golomb(code):
            return code
    raise ValueError(f"No Golomb ruler of {chips} marks found within {slots} slots")


def mean_period_cycles(point):
    """Mean time between the starts of two of the victim's TDC windows (pulses, or bursts for
    ``code``), in clock cycles."""
    period = point["period_cycles"]
    scheme = point["scheme"]
    if scheme == "hopping":
        return period + point["hop_step_cycles"] * (point["hop_periods"] - 1) / 2
    if scheme == "fliss":
        return period + float(_delay.mean_delay(point["delay_mode"], length=point["length"],
                                                mask_width=point["mask_width"]))
    return float(period)


@lru_cache(maxsize=128)
def _fliss_cycles(mode, length, mask_width, seed, period, block):
    """The first ``block`` edges of a delay core in clock cycles (``float64``, read-only),
    kept for the few seeds of ``mseq`` (63 for L = 6)."""
    settings = _scheduler.Settings(mode=_delay.parse_mode(mode), length=length,
                                   mask_width=mask_width, seed=seed, period=period)
    edges = EdgeSchedule(settings, block)().astype(np.float64)
    edges.flags.writeable = False
    return edges


def _draw_seed(rng, point):
    bits = point["length"] if point["delay_mode"] == "mseq" else 32
    return int(rng.integers(1, 1 << bits))


@dataclass
class Camera:
    """One camera of a frame: its scheme's settings (a checked point), its oscillator and its
    own random choices, drawn from ``rng`` by :meth:`draw`."""

    point: dict
    phase_lsb: float
    ppm: float
    seed: int = 1
    code: np.ndarray = None
    hop_rng: np.random.Generator = None

    @classmethod
    def draw(cls, point, rng, *, victim=False):
        """The victim (no phase, the reference oscillator) or an aggressor (a start uniform over
        one period, an offset uniform in ``± ppm_spread`` ppm)."""
        period_lsb = point["period_cycles"] * LSB_PER_CYCLE
        phase = 0.0 if victim else float(rng.uniform(0.0, period_lsb))
        ppm = 0.0 if victim else float(rng.uniform(-1.0, 1.0) * point["ppm_spread"])
        camera = cls(point, phase, ppm)
        scheme = point["scheme"]
        if scheme == "fliss":
            camera.seed = _draw_seed(rng, point)
        elif scheme == "code":
            camera.code = golomb_code(rng, point["code_chips"], point["code_slots"])
        elif scheme == "hopping":
            camera.hop_rng = np.random.default_rng(rng.integers(0, 1 << 63))
        return camera

    @property
    def chip_offsets_lsb(self):
        """Offsets of the pulses of one burst from its start (``[0.]`` but for ``code``)."""
        if self.point["scheme"] != "code":
            return np.zeros(1)
        return self.code * (self.point["code_slot_cycles"] * LSB_PER_CYCLE)

    def _cycles(self, count):
        """Start of each of the first ``count`` bursts, in the camera's own clock cycles."""
        point = self.point
        period = point["period_cycles"]
        scheme = point["scheme"]
        if scheme == "fliss":
            # Block lengths in steps of 2048 pulses: the masked source caches its basis per
            # length (a few lengths serve every camera of a point)
            block = 2048 * -(-count // 2048)
            return _fliss_cycles(point["delay_mode"], point["length"], point["mask_width"],
                                 self.seed, period, block)[:count]
        if scheme == "hopping":
            dwell = point["hop_dwell"]
            dwells = -(-count // dwell) + 1
            hops = self.hop_rng.integers(0, point["hop_periods"], dwells)
            periods = np.repeat(period + point["hop_step_cycles"] * hops, dwell)
            cut = int(self.hop_rng.integers(0, dwell))
            return np.cumsum(periods[cut:cut + count], dtype=np.float64)
        return period * np.arange(1, count + 1, dtype=np.float64)

    def bursts(self, start_lsb, end_lsb):
        """Start of every burst (every pulse but for ``code``) from ``start_lsb`` to
        ``end_lsb``, in the victim's LSBs."""
        scale = LSB_PER_CYCLE / (1.0 + self.ppm * 1e-6)
        first = start_lsb + self.phase_lsb
        count = max(1, math.ceil((end_lsb - first) / (self.point["period_cycles"] * scale)) + 1)
        cycles = self._cycles(count)
        times = first + (cycles - cycles[0]) * scale
        return times[times < end_lsb]

    def pulses(self, start_lsb, end_lsb):
        """Every pulse's emission, in the victim's LSBs: ``(bursts, chip offsets)`` flattened,
        burst after burst."""
        bursts = self.bursts(start_lsb, end_lsb)
        return (bursts[:, None] + self.chip_offsets_lsb[None, :]).ravel()
