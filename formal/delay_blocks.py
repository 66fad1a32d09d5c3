"""Formal harnesses of the delay core's blocks alone: the laser trigger (``hdl/delay/laser.py``),
the delay source (``hdl/delay/source.py``) and the LFSR (``hdl/delay/lfsr.py``), with the small
settings of the core's harness (``formal/delay_core.py``).

Each proof has a mutant: the harness around a broken block (``formal/_mutants.py``).
"""

from amaranth.hdl import Assert, Assume, Const, Cover, Module, Mux, ResetSignal, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In

from ..hdl.delay.laser import LaserTrigger
from ..hdl.delay.lfsr import POLYNOMIALS, Lfsr
from ..hdl.delay.modes import DelayMode
from ..hdl.delay.source import DelaySource

from ._harness import past
from ._mutants import _LateStartTrigger, _OffByOneSource, _RuntTrigger, _ZeroLoadingLfsr
from .delay_core import PULSE_WIDTH_WIDTH, SETTINGS, assume_valid, max_delay
from .runner import Proof, internals


__all__ = ["TriggerHarness", "SourceHarness", "LfsrHarness", "PROOFS"]


# Laser trigger alone

class TriggerHarness(wiring.Component):
    """The laser trigger alone, with ``fire`` and ``width`` free. ``check``: ``"start"``, the
    TDC start strobes in the cycle of every rising edge of the laser, and only while the laser is
    on; ``"width"``, with ``fire`` only while the laser is off (the scheduler's part, proved on
    the core by ``delay_core.pulses``), every pulse is exactly ``width`` cycles high (zero acting
    as one)."""

    fire:  In(1)
    width: In(PULSE_WIDTH_WIDTH)

    def __init__(self, trigger=LaserTrigger, check="start"):
        self._trigger = trigger
        self._check = check
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        trigger = self._trigger(width_bits=PULSE_WIDTH_WIDTH)
        if self._check == "width" and self._trigger is LaserTrigger:
            m.submodules.trigger, (remaining,) = internals(trigger, "remaining")
        else:
            remaining = None
            m.submodules.trigger = trigger
        m.d.comb += [trigger.fire.eq(self.fire), trigger.width.eq(self.width)]
        m.d.comb += Assume(~ResetSignal())
        laser_d = past(m, trigger.laser)
        rise = trigger.laser & ~laser_d
        if self._check == "start":
            m.d.comb += [Assert(~rise | trigger.tdc_start),
                         Assert(~trigger.tdc_start | trigger.laser), Cover(rise)]
            return m

        m.d.comb += Assume(~self.fire | ~trigger.laser)
        width = Signal(PULSE_WIDTH_WIDTH)       # width of the pulse on the laser
        with m.If(self.fire):
            m.d.sync += width.eq(Mux(self.width == 0, 1, self.width))
        high = Signal(PULSE_WIDTH_WIDTH)        # cycles the laser has been high before this one
        m.d.sync += high.eq(Mux(trigger.laser, high + 1, 0))
        fall = ~trigger.laser & laser_d
        m.d.comb += [Assert(~trigger.laser | (high < width)),
                     Assert(~fall | (high == width)),
                     Cover(fall & (high == 7)), Cover(fall & (high == 1))]
        if remaining is not None:
            m.d.comb += Assert(Mux(trigger.laser, remaining + high == width - 1, remaining == 0))
        return m


# Delay source

class SourceHarness(wiring.Component):
    """The delay source with free ``load``, transfers and valid settings: every delay is within
    ``0 … 2**L - 2`` (``mseq``), ``0 … 2**Wm - 1`` (``masked``), or zero (``off``), for the
    settings sampled on the last load."""

    load:     In(1)
    ready:    In(1)
    settings: In(SETTINGS)

    def __init__(self, source=DelaySource):
        self._source = source
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        source = self._source(layout=SETTINGS)
        invariants = self._source is DelaySource
        if invariants:
            m.submodules.source, (s_mode, s_mask, s_keyed_mask, s_taps, s_mseq, s_masked) = \
                internals(source, "mode", "mask", "keyed_mask", "taps", "mseq", "masked")
        else:
            m.submodules.source = source
        m.d.comb += [source.load.eq(self.load), source.settings.eq(self.settings),
                     source.delays.ready.eq(self.ready)]
        m.d.comb += Assume(~ResetSignal())
        assume_valid(m, self.settings, max_l=32, max_wm=16)
        # transfers at least two cycles apart, as the scheduler makes them
        m.d.comb += Assume(~(self.ready & past(m, self.ready)))

        # settings of the last load, and the largest delay and the taps they give
        mode = Signal(DelayMode)
        length = Signal.like(self.settings.length, init=32)
        mask_width = Signal.like(self.settings.mask_width)
        with m.If(self.load):
            m.d.sync += [mode.eq(self.settings.mode), length.eq(self.settings.length),
                         mask_width.eq(self.settings.mask_width)]
        top = max_delay(m, mode, {"length": length, "mask_width": mask_width}, "top")
        taps = Signal(32)
        with m.Switch(length):
            for bits, poly in POLYNOMIALS.items():
                with m.Case(bits):
                    m.d.comb += taps.eq(poly >> 1)
        value = source.delays.payload.value
        if invariants:
            # the source's registers agree with the settings of the last load
            m.d.comb += [Assert(s_mode == mode.as_value()), Assert(s_taps == taps),
                         Assert(s_mask == Mux(mode == DelayMode.MASKED, top, 0)),
                         Assert(s_keyed_mask == 0),     # (the keyed mode is assumed off)
                         Assert(s_mseq <= Mux(mode == DelayMode.MSEQ, top + 1, 1)),
                         # the masked register never holds zero (the m-sequence one holds zero
                         # only standing for 1: `value <= top` below shows it is never 0 - 1)
                         Assert(s_masked != 0)]
        m.d.comb += [Assert(value <= top),
                     Cover((mode == DelayMode.MSEQ) & (value == top) & (top == 6)),
                     Cover((mode == DelayMode.MASKED) & (value == top) & (top == 3))]
        return m


class LfsrHarness(wiring.Component):
    """The LFSR with free ``seed``, ``load`` and ``advance``: it never holds zero, nor a bit at
    or above its length (the length sampled on the last load)."""

    seed:    In(32)
    load:    In(1)
    advance: In(1)
    length:  In(range(2, 33))

    def __init__(self, lfsr=Lfsr, **kwargs):
        self._lfsr = lfsr
        self._kwargs = kwargs
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        lfsr = self._lfsr(**self._kwargs)
        fixed = self._kwargs.get("length")
        if fixed is None and self._lfsr is Lfsr:
            m.submodules.lfsr, (l_length,) = internals(lfsr, "length")
        else:
            m.submodules.lfsr = lfsr
        m.d.comb += [lfsr.seed.eq(self.seed), lfsr.load.eq(self.load),
                     lfsr.advance.eq(self.advance)]
        m.d.comb += Assume(~ResetSignal())
        if fixed is None:
            m.d.comb += lfsr.length.eq(self.length)
            raw = Signal(range(2, 33), init=32)
            with m.If(self.load):
                m.d.sync += raw.eq(self.length)
            if self._lfsr is Lfsr:
                m.d.comb += Assert(l_length == raw)
            length = Mux((raw >= 2) & (raw <= 32), raw, 32)
            bound = Const(1, 33) << length
        else:
            bound = 1 << fixed
        m.d.comb += [Assert(lfsr.state != 0), Assert(lfsr.state < bound),
                     Cover(self.load & (self.seed == 0)),
                     Cover((lfsr.state == bound - 1) & self.advance)]
        return m


def _zero_loading(**kwargs):
    return _ZeroLoadingLfsr(length=kwargs.get("length"))


PROOFS = [
    Proof("delay_blocks.trigger_start", TriggerHarness, "prove", 2,
          "laser trigger: a TDC start in every rising edge's cycle, and only while the laser is on",
          mutant=lambda: TriggerHarness(_LateStartTrigger)),
    Proof("delay_blocks.trigger_width", lambda: TriggerHarness(check="width"), "prove", 2,
          "laser trigger, fired only while the laser is off: every pulse exactly width cycles "
          "high (zero acting as one)",
          mutant=lambda: TriggerHarness(_RuntTrigger, check="width")),
    Proof("delay_blocks.source_range", SourceHarness, "prove", 2,
          "delay source: R within 0 … 2^L − 2 (mseq), 0 … 2^Wm − 1 (masked), 0 (off); "
          "its registers never hold zero (L 2 … 32, Wm 1 … 16)",
          mutant=lambda: SourceHarness(_OffByOneSource)),
    Proof("delay_blocks.lfsr_fixed", lambda: LfsrHarness(length=5, steps=3), "prove", 1,
          "LFSR (L = 5, 3 steps per advance): never zero, nothing above bit L − 1",
          mutant=lambda: LfsrHarness(_zero_loading, length=5)),
    Proof("delay_blocks.lfsr_runtime", LfsrHarness, "prove", 1,
          "LFSR (run-time L): never zero, nothing above bit L − 1 of the loaded L",
          mutant=lambda: LfsrHarness(_zero_loading)),
]
