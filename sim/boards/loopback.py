"""The photon input of the model board looped back to a laser trigger: the self-test's bench.

A :class:`Loopback` says what reaches the TDCs and with what delay and jitter:

* the jumper wire (``jumper``) on the photon input: the victim's laser trigger (``"laser"``),
  the aggressor's (``"aggressor"``) or nothing (``None``: the scene's photons), ``delay_s``
  after the trigger's clock edge;
* the fine TDC's on-chip oscillator (``tdc_input`` 1): hits uniform over the clock period, at
  ``oscillator_hz``, for the code-density calibration;
* the fine TDC's internal loopback (``tdc_input`` 2, the laser's pad read back; 3, the
  aggressor's): the trigger's edge ``pad_delay_s`` after its clock edge, no jumper needed.

Both loopbacks have the Gaussian jitter ``jitter_s``.

:meth:`LoopbackRun.events` gives the events of a run of clock cycles as the board's TDC makes them:
the coarse TDC (``tdc_source`` 1) counts the clock cycles from the TDC start's to the hit's
(a hit less than a cycle after its trigger's clock edge is code 0, as on the board); the fine
TDC (2 and 3) samples the modelled line (:class:`fliss.sim.models.finetdc.Line`) at the first
edge after the hit and looks the raw code up in the board's calibration table, as
:func:`fliss.sim.models.finetdc.captures` does. The pulses fire as the pulse scheduler fires
them (:func:`fliss.sim.models.scheduler.fire_cycles`, the delays of
:mod:`fliss.sim.models.delay` from the seed at each START); the aggressor with no delays of its
own fires ``aggressor_offset + 1 + k T`` cycles after the start. ``wrong_delay_every`` (a fault,
for tests) adds a cycle to every n-th delay of the victim while its delays are on.
"""

from dataclasses import dataclass, field

import numpy as np

from ...hdl.delay.modes import DelayMode
from ...hdl.event import PULSE_BITS, TIMESTAMP_BITS
from ...hdl.finetdc import HitInput
from ...hdl.clock import cycle_units
from ...hdl.registers import TdcSource
from ...protocol.events import EVENT_DTYPE
from ..models import scheduler as _scheduler
from ..models.finetdc import Line


__all__ = ["JUMPERS", "JUMPER_DELAY_S", "PAD_DELAY_S", "JITTER_S", "Loopback"]


#: What a jumper wire can carry to the photon input.
JUMPERS = ("laser", "aggressor")
#: The models' jumper wire: from the trigger's clock edge through its flip-flop, the output
#: buffer, some centimetres of wire and the photon pin's input buffer to the fine TDC's
#: multiplexer.
JUMPER_DELAY_S = 3.2e-9
#: The models' internal loopback: from the trigger's clock edge through its flip-flop, the
#: output buffer and the same pad's input buffer to the fine TDC's multiplexer: the jumper's
#: path without the wire and the second pad's routing (a stated model value: the board's own
#: is what the self-test prints).
PAD_DELAY_S = 2.5e-9
#: The models' RMS jitter of both loopbacks.
JITTER_S = 20e-12
#: ``tdc_input`` -> the trigger its internal loopback reads back.
_PADS = {HitInput.LASER.value: "laser", HitInput.AGGRESSOR.value: "aggressor"}


@dataclass(frozen=True)
class Loopback:
    """A loopback of the model board (see the module's description)."""
    jumper: object = "laser"
    delay_s: float = JUMPER_DELAY_S
    jitter_s: float = JITTER_S
    oscillator_hz: float = 2.4e6
    pad_delay_s: float = PAD_DELAY_S
    line: Line = field(default_factory=Line)
    wrong_delay_every: object = None
    seed: int = 5

    def __post_init__(self):
        if self.jumper is not None and self.jumper not in JUMPERS:
            raise ValueError(f"A jumper carries one of {', '.join(JUMPERS)} or nothing, "
                             f"not {self.jumper!r}")
        for name in ("delay_s", "jitter_s", "oscillator_hz", "pad_delay_s"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must not be negative, not {getattr(self, name)!r}")

    def hits(self, settings):
        """What drives the TDC with register ``settings``, and with what delay after the
        trigger's clock edge: ``("laser", delay)``, ``("aggressor", delay)``,
        ``("oscillator", None)``, or ``(None, None)`` (the scene's photons)."""
        source = settings["tdc_source"]
        if source == TdcSource.SENSOR.value:
            return None, None
        if source in (TdcSource.FINE.value, TdcSource.FINE_RAW.value):
            if settings["tdc_input"] == HitInput.OSCILLATOR.value:
                return "oscillator", None
            if settings["tdc_input"] in _PADS:
                return _PADS[settings["tdc_input"]], self.pad_delay_s
        return self.jumper, (self.delay_s if self.jumper else None)

    def run(self, settings, victim, clock_hz, table, seed):
        """A :class:`LoopbackRun` for one acquisition (``victim``: the victim's
        :class:`fliss.sim.models.scheduler.Settings`; ``table``: the board's calibration
        table)."""
        return LoopbackRun(self, settings, victim, clock_hz, table, seed)


class LoopbackRun:
    """The loopback's hits of one acquisition, a run of clock cycles at a time."""

    def __init__(self, loopback, settings, victim, clock_hz, table, seed):
        self.loopback = loopback
        self.settings = dict(settings)
        self.victim = victim
        self.clock_hz = clock_hz
        self.table = np.asarray(table, dtype=np.int64)
        self.rng = np.random.default_rng([loopback.seed, *seed.generate_state(2)])
        self.kind, self.delay_s = loopback.hits(settings)
        self.starts = np.zeros(0, dtype=np.int64)
        self._fires_until = 0

    def _extend_starts(self, end):
        # Victim start cycles up to `end` (delays restart from the seed at each START)
        victim = self.victim
        count = max(16, len(self.starts) * 2)
        while not len(self.starts) or self.starts[-1] < end:
            delays = victim.delays(count)
            every = self.loopback.wrong_delay_every
            if every and victim.mode != DelayMode.OFF:
                delays = delays.copy()
                delays[every - 1::every] += 1
            self.delays = delays
            self.starts = _scheduler.fire_cycles(delays, victim.period, grid=victim.grid)
            count *= 2

    def events(self, begin, end):
        """The events of hits in clock cycles ``[begin, end)``, or None if the loopback does
        not drive the TDC (then the scene's photons do)."""
        if self.kind is None:
            return None
        cycle_s = 1 / self.clock_hz
        self._extend_starts(end + 1)
        rng = self.rng
        if self.kind == "oscillator":
            count = rng.poisson((end - begin) * cycle_s * self.loopback.oscillator_hz)
            hits_s = np.sort(rng.uniform(begin, end, count)) * cycle_s
        else:
            if self.kind == "aggressor":
                s = self.settings
                fires = s["aggressor_offset"] + 1 + \
                    np.arange(end // s["aggressor_period"] + 2) * s["aggressor_period"]
            else:
                fires = self.starts
            fires = fires[(fires >= begin) & (fires < end)]
            hits_s = fires * cycle_s + self.delay_s + \
                rng.normal(0, self.loopback.jitter_s, len(fires))
        return self._timestamps(hits_s, cycle_s)

    def _timestamps(self, hits_s, cycle_s):
        # Sampled at the first edge after the hit, timed from the last start at or before it
        sampled = np.floor(hits_s / cycle_s).astype(np.int64) + 1
        tau_s = sampled * cycle_s - hits_s
        s = self.settings
        if s["tdc_source"] == TdcSource.COARSE.value:
            # The coarse TDC counts the cycle that edge closes (the hit's own): the cycles from
            # the start's to the hit's (fliss.hdl.tdc.CoarseTdc)
            sampled -= 1
        else:
            # A hit that has not reached the first tap by the edge is the next edge's
            codes = self.loopback.line.codes(tau_s, self.rng)
            late = codes == 0
            sampled[late] += 1
            codes[late] = self.loopback.line.codes(tau_s[late] + cycle_s, self.rng)
            codes = np.clip(codes, 0, len(self.table) - 1)
        index = np.searchsorted(self.starts, sampled, side="right") - 1
        started = index >= 0
        start = self.starts[np.maximum(index, 0)]
        if s["tdc_source"] == TdcSource.COARSE.value:
            stamps = sampled - start
        elif s["tdc_source"] == TdcSource.FINE_RAW.value:
            stamps, started = codes, np.ones(len(codes), bool)
        else:
            ticks = (sampled - start) * cycle_units(self.clock_hz) - self.table[codes]
            started &= ticks >= 0
            stamps = np.maximum(ticks, 0) >> (2 - s["fine_lsb"])
        kept = started & (stamps < (1 << TIMESTAMP_BITS))
        events = np.zeros(int(np.count_nonzero(kept)), dtype=EVENT_DTYPE)
        events["timestamp"] = stamps[kept]
        events["pulse"] = index[kept] % (1 << PULSE_BITS)
        return events, int(np.count_nonzero(~kept))
