"""Formal harnesses of the delay core (``hdl/delay/core.py``): laser trigger, pulse scheduler, delay
source and LFSR.

The core is proved with small settings, as the register file would accept them: ``period`` from
2 to :data:`MAX_PERIOD` (a 17-bit ``period``, the narrowest the scheduler takes), a 3-bit
``pulse_width`` from 1 to ``period - 1``, register lengths ``L`` up to :data:`MAX_L` and mask
widths ``Wm`` up to :data:`MAX_WM`; in ``grid`` mode the largest delay plus the pulse width is
below the period. ``enable`` and ``update`` are free in every cycle.

Mutants swap a block of the core for a broken one (``formal/_mutants.py``, and those of the
settings proofs below) while the core elaborates (:class:`_ProbedCore`).
"""

from amaranth.hdl import Assert, Assume, Cat, Cover, Const, Module, Mux, ResetSignal, Signal, Value
from amaranth.lib import wiring
from amaranth.lib.wiring import In

import fliss.hdl.delay.core as core_module
from ..hdl.delay.core import DelayCore
from ..hdl.delay.source import DelayMode, DelaySource
from ..hdl.delay.laser import LaserTrigger
from ..hdl.delay.lfsr import POLYNOMIALS, Lfsr
from ..hdl.registers import DelaySettings
from ..hdl.delay.scheduler import PulseScheduler, _Timer

from ._harness import assigned
from ._mutants import (_EagerWidthScheduler, _LateStartTrigger, _LateStopScheduler,
                       _LongPeriodScheduler, _NoDelayScheduler, _OffByOneSource, _RuntTrigger,
                       _Wrapper, _ZeroLoadingLfsr)
from .runner import Proof, internals


#: Small settings of the core harness.
PERIOD_WIDTH, PULSE_WIDTH_WIDTH, MAX_PERIOD, MAX_L, MAX_WM = 17, 3, 10, 3, 2
SETTINGS = DelaySettings(period_width=PERIOD_WIDTH, pulse_width_width=PULSE_WIDTH_WIDTH)


def _past(m, value):
    """``value`` in the previous cycle (its initial value in the first)."""
    past = Signal.like(value, name="past")
    m.d.sync += past.eq(value)
    return past


def _assume_valid(m, settings, *, max_l=MAX_L, max_wm=MAX_WM):
    """Settings the register file accepts, small."""
    max_delay = Signal(33)
    with m.Switch(settings.mode):
        with m.Case(DelayMode.MSEQ):
            m.d.comb += max_delay.eq((Const(1, 33) << settings.length) - 2)
        with m.Case(DelayMode.MASKED):
            m.d.comb += max_delay.eq((Const(1, 33) << settings.mask_width) - 1)
    m.d.comb += [
        Assume(settings.mode.as_value() != 3),
        Assume((settings.length >= 2) & (settings.length <= max_l)),
        Assume((settings.mask_width >= 1) & (settings.mask_width <= max_wm)),
        Assume((settings.period >= 2) & (settings.period <= MAX_PERIOD)),
        Assume((settings.pulse_width >= 1) & (settings.pulse_width < settings.period)),
        Assume(~settings.grid | (max_delay + settings.pulse_width < settings.period)),
    ]


class _ProbedCore(DelayCore):
    """The delay core, with the scheduler's take cycle and pulse width brought out, and blocks
    swapped for mutants (``swaps``: name in ``hdl/delay/core.py`` -> class)."""

    def __init__(self, swaps=None):
        super().__init__(period_width=PERIOD_WIDTH, pulse_width_width=PULSE_WIDTH_WIDTH)
        self.swaps = swaps or {}
        self.take = Signal()
        self.fire_width = Signal(PULSE_WIDTH_WIDTH)
        self.take_value = Signal(32)

    def elaborate(self, platform):
        saved = {name: getattr(core_module, name) for name in self.swaps}
        try:
            for name, block in self.swaps.items():
                setattr(core_module, name, block)
            m = super().elaborate(platform)
        finally:
            for name, block in saved.items():
                setattr(core_module, name, block)
        scheduler = m.submodules.scheduler
        m.d.comb += [self.take.eq(scheduler.delays.ready),
                     self.fire_width.eq(scheduler.fire_width),
                     self.take_value.eq(scheduler.delays.payload.value)]
        return m


# Delay core

class CoreHarness(wiring.Component):
    """The delay core with free ``enable``, ``update`` and valid settings; ``check`` names the
    property asserted. ``fixed`` settings stay put while running, and ``update`` stays low."""

    enable:   In(1)
    update:   In(1)
    settings: In(SETTINGS)

    def __init__(self, check, *, swaps=None, fixed=False):
        self.check = check
        self.swaps = swaps
        self.fixed = fixed
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.core = core = _ProbedCore(self.swaps)
        m.d.comb += [core.enable.eq(self.enable), core.update.eq(self.update),
                     core.settings.eq(self.settings)]
        m.d.comb += Assume(~ResetSignal())
        _assume_valid(m, self.settings)
        enable_d = _past(m, self.enable)
        if self.fixed:
            settings_d = _past(m, self.settings)
            m.d.comb += [Assume(~self.update), Assume(~core.running | (self.settings == settings_d))]

        laser_d = _past(m, core.laser)
        rise = core.laser & ~laser_d
        fire_width = Signal(PULSE_WIDTH_WIDTH)    # width of the pulse on the laser
        with m.If(core.fire):
            m.d.sync += fire_width.eq(core.fire_width)
        high = Signal(PULSE_WIDTH_WIDTH + 1)      # cycles the laser has been high
        m.d.sync += high.eq(Mux(core.laser, high + 1, 0))
        fired = Signal()                          # a pulse fired since the start
        since = Signal(8)                         # cycles since the last pulse of this run
        slot = Signal(8)                          # grid: cycle in this slot, from the take
        slot_index = Signal(8)                    # grid: slot since the start
        with m.If(~core.running):
            m.d.sync += [fired.eq(0), since.eq(0), slot.eq(0), slot_index.eq(0)]
        with m.Else():
            m.d.sync += since.eq(Mux(core.fire, 1, since + 1))
            m.d.sync += fired.eq(fired | core.fire)
            last = slot == self.settings.period - 1
            m.d.sync += [slot.eq(Mux(last, 0, slot + 1)), slot_index.eq(slot_index + last)]

        if self.check == "start":
            m.d.comb += [Assert(rise == core.tdc_start), Cover(rise & fired)]
        elif self.check == "interval":
            gap = self.settings.period + core.fire_delay
            with m.If(core.fire & fired & ~self.settings.grid):
                m.d.comb += [Assert(since == gap), Assert(since >= self.settings.period)]
            m.d.comb += Cover(core.fire & fired & ~self.settings.grid & (core.fire_delay > 1))
        elif self.check == "grid":
            with m.If(core.fire & self.settings.grid):
                m.d.comb += [Assert(slot_index == core.pulse_index[:8]),
                             Assert(slot == 1 + core.fire_delay)]
            m.d.comb += Cover(core.fire & self.settings.grid & (core.pulse_index == 2)
                              & (core.fire_delay > 0))
        elif self.check == "disabled":
            stopped = Signal(PULSE_WIDTH_WIDTH + 1)   # cycles since enable fell, saturating
            m.d.sync += stopped.eq(Mux(self.enable, 0, Mux(stopped[-1], stopped, stopped + 1)))
            m.d.comb += [Assert(~core.fire | self.enable), Assert(~rise | enable_d),
                         Assert(~stopped[-1] | ~core.laser),
                         Cover(~self.enable & core.laser & fired)]
        elif self.check == "settings":
            # the model of the contract: settings sampled while stopped or on update apply from
            # the first take cycle after the sampling cycle
            pending = Signal()
            pending_width = Signal(PULSE_WIDTH_WIDTH)
            width = Signal(PULSE_WIDTH_WIDTH)
            take_d = _past(m, core.take)
            with m.If(core.take):
                m.d.sync += [width.eq(Mux(pending, pending_width, width)), pending.eq(0)]
            with m.If(~core.running | self.update):
                m.d.sync += [pending.eq(1), pending_width.eq(self.settings.pulse_width)]
            width_d = _past(m, core.fire_width)
            m.d.comb += [Assert(take_d | (core.fire_width == width_d)),
                         Assert(core.fire_width == width),
                         Cover(self.update & core.running & (self.settings.pulse_width != width)
                               & fired & core.fire)]
        elif self.check in ("settings_period", "settings_source"):
            self._frames(m, core, enable_d)
        elif self.check == "pulses":
            fall = ~core.laser & laser_d
            m.d.comb += [Assert(~core.laser | (high < fire_width)),
                         Assert(~fall | (high == fire_width)),
                         Assert(~core.tdc_start | ~laser_d),
                         Cover(fall & (high == 3) & ~self.enable)]
        else:
            raise ValueError(f"Unknown check {self.check!r}")
        return m


    def _frames(self, m, core, enable_d):
        """Every other setting also applies from the first take after it is sampled: the
        period and mode of a frame (``settings_period``: its length), and the delay source's
        (``settings_source``: the frame's delay is the seed's if settings were sampled since the
        take before, else within the range of the settings sampled last before its take; it
        stays the frame's, and times its pulse)."""
        settings = self.settings
        sample = ~core.running | self.update
        age = Signal(8)         # cycles since the last take of this run (0 before the first)
        took = Signal()         # a take in this run
        with m.If(~core.running):
            m.d.sync += [age.eq(0), took.eq(0)]
        with m.Else():
            m.d.sync += [age.eq(Mux(core.take, 1, age + 1)), took.eq(took | core.take)]
        # timed from the frame's own delay, whatever comes after its take
        m.d.comb += Assert(~core.fire | (age == 1 + core.fire_delay))
        if self.check == "settings_period":
            pending, (period, grid) = _frame_settings(
                m, core.take, sample, settings.period, settings.grid)
            # a frame's length: T (grid) or T + R (interval) of the settings of its take
            length = Mux(grid, period, period + core.fire_delay)
            m.d.comb += Assert(~(core.take & took) | (age == length))
            changed = Signal()      # an update in this frame to another period or mode
            with m.If(core.take):
                m.d.sync += changed.eq(0)
            with m.Elif(self.update & core.running & ((settings.period != period)
                                                      | (settings.grid != grid))):
                m.d.sync += changed.eq(1)
            m.d.comb += [Cover(core.take & took & changed & ~grid & (core.fire_delay > 0)),
                         Cover(core.take & took & changed & grid)]
            return
        pending, (p_mode, p_length, p_mask_width, p_seed), (mode, length, mask_width, _) = \
            _frame_settings(m, core.take, sample, settings.mode.as_value(), settings.length,
                            settings.mask_width, settings.seed, pending_too=True)
        new_mode = Mux(pending, p_mode, mode)
        new_length = Mux(pending, p_length, length)
        new_mask_width = Mux(pending, p_mask_width, mask_width)
        # the first delay after a sample comes from the seed (`hdl/delay/lfsr.py` `Lfsr`: the
        # m-sequence register seeded with the seed's low L bits, zero standing for 1), the
        # others are within the range of the frame's settings
        first = Signal(32)
        top = Signal(32)
        with m.Switch(new_length):
            for bits in range(2, MAX_L + 1):
                with m.Case(bits):
                    seeded = p_seed[:bits]
                    with m.If(new_mode == DelayMode.MSEQ):
                        m.d.comb += [first.eq(Mux(seeded == 0, 0, seeded - 1)),
                                     top.eq((1 << bits) - 2)]
        seeded_masked = Cat(p_seed[0] | (p_seed[1:] == 0), p_seed[1:MAX_WM])
        with m.If(new_mode == DelayMode.MASKED):
            with m.Switch(new_mask_width):
                for bits in range(1, MAX_WM + 1):
                    with m.Case(bits):
                        m.d.comb += [first.eq(seeded_masked[:bits]), top.eq((1 << bits) - 1)]
        expected_ok = Mux(pending, core.take_value == first, core.take_value <= top)
        fire_delay_d = _past(m, core.fire_delay)
        take_d = _past(m, core.take)
        m.d.comb += [Assert(~core.take | expected_ok),
                     Assert(take_d | (core.fire_delay == fire_delay_d))]
        changed = Signal()      # an update in this frame to other source settings
        with m.If(core.take):
            m.d.sync += changed.eq(0)
        with m.Elif(self.update & core.running & (settings.mode.as_value() != mode)):
            m.d.sync += changed.eq(1)
        m.d.comb += [Cover(core.fire & changed & (core.fire_delay > 0)),
                     Cover(core.take & took & ~pending & (mode == DelayMode.MASKED)
                           & (core.take_value > 0))]


def _frame_settings(m, take, sample, *values, pending_too=False):
    """The model of the contract: ``values`` sampled in a ``sample`` cycle apply from the first
    take cycle after it. Returns ``pending`` (sampled since the last take) and the values of the
    current frame (and, ``pending_too``, first the values sampled)."""
    pending = Signal(name="model_pending")
    sampled = [Signal(len(Value.cast(value)), name="model_sampled") for value in values]
    active = [Signal(len(Value.cast(value)), name="model_active") for value in values]
    with m.If(take):
        m.d.sync += [a.eq(Mux(pending, s, a)) for a, s in zip(active, sampled)]
        m.d.sync += pending.eq(0)
    with m.If(sample):
        m.d.sync += [pending.eq(1)] + [s.eq(v) for s, v in zip(sampled, values)]
    if pending_too:
        return pending, sampled, active
    return pending, active


class _MidFramePeriodScheduler(PulseScheduler):
    """Loads a new period on ``update``, in the middle of a frame (not at the next take)."""

    def elaborate(self, platform):
        m = super().elaborate(platform)
        period, flags = assigned(m, "active_period", "active_flags")
        with m.If(self.update):
            m.d.sync += [period.eq(self.settings.period),
                         flags.eq(_Timer.flags(self.settings.period, target=2))]
        return m


class _LiveSettingsSource(_Wrapper):
    """A delay source that samples the settings in every cycle, not only on ``load``."""

    def __init__(self, **kwargs):
        super().__init__(DelaySource(**kwargs))

    def elaborate(self, platform):
        return self.forward(Module(), load=Const(1))


def _core(check, depth, doc, swaps, *, fixed=False, mode="bmc", cover_depth=None):
    return Proof(f"delay_core.{check}", lambda: CoreHarness(check, fixed=fixed), mode, depth,
                 doc, mutant=lambda: CoreHarness(check, fixed=fixed, swaps=swaps),
                 cover_depth=cover_depth)


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
        _assume_valid(m, self.settings, max_l=32, max_wm=16)
        # transfers at least two cycles apart, as the scheduler makes them
        m.d.comb += Assume(~(self.ready & _past(m, self.ready)))

        # settings of the last load, and the largest delay and the taps they give
        mode = Signal(DelayMode)
        length = Signal.like(self.settings.length, init=32)
        mask_width = Signal.like(self.settings.mask_width)
        with m.If(self.load):
            m.d.sync += [mode.eq(self.settings.mode), length.eq(self.settings.length),
                         mask_width.eq(self.settings.mask_width)]
        top = Signal(33)
        with m.Switch(mode):
            with m.Case(DelayMode.MSEQ):
                m.d.comb += top.eq((Const(1, 33) << length) - 2)
            with m.Case(DelayMode.MASKED):
                m.d.comb += top.eq((Const(1, 33) << mask_width) - 1)
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


# LFSR

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
        laser_d = _past(m, trigger.laser)
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


def _zero_loading(**kwargs):
    return _ZeroLoadingLfsr(length=kwargs.get("length"))


PROOFS = [
    Proof("delay_core.trigger_start", TriggerHarness, "prove", 2,
          "laser trigger: a TDC start in every rising edge's cycle, and only while the laser is on",
          mutant=lambda: TriggerHarness(_LateStartTrigger)),
    Proof("delay_core.trigger_width", lambda: TriggerHarness(check="width"), "prove", 2,
          "laser trigger, fired only while the laser is off: every pulse exactly width cycles "
          "high (zero acting as one)",
          mutant=lambda: TriggerHarness(_RuntTrigger, check="width")),
    _core("start", 40, "the laser's rising edge and the TDC start are always in the same cycle",
          {"LaserTrigger": _LateStartTrigger}),
    _core("interval", 40, "interval mode: consecutive pulses exactly T + R apart, never closer "
          "than T", {"PulseScheduler": _NoDelayScheduler}, fixed=True),
    _core("grid", 32, "grid mode: pulse k fires at k T + 1 + R[k] after the start, inside "
          "slot k", {"PulseScheduler": _LongPeriodScheduler}, fixed=True),
    _core("disabled", 10, "no pulse while disabled: no fire, no rising edge, the laser off "
          "once the last pulse ends", {"PulseScheduler": _LateStopScheduler}, mode="prove",
          cover_depth=30),
    _core("settings", 40, "settings (the pulse width) change only at a frame boundary, from "
          "the first take after they are sampled", {"PulseScheduler": _EagerWidthScheduler}),
    _core("settings_period", 40, "the period and the mode change only at a frame boundary: a "
          "frame lasts T (grid) or T + R (interval) of the settings sampled before its take, "
          "and its pulse fires R + 1 after it", {"PulseScheduler": _MidFramePeriodScheduler}),
    _core("settings_source", 30, "the delay source's settings (mode, L, Wm, seed) change only "
          "at a frame boundary: a frame's delay is the seed's after a sample, else within the range "
          "of the settings sampled before its take, and stays the frame's",
          {"DelaySource": _LiveSettingsSource}),
    _core("pulses", 40, "no runt, merged or doubled pulse: each exactly pulse_width cycles "
          "high, low at least one cycle between", {"LaserTrigger": _RuntTrigger}),
    Proof("delay_core.source_range", SourceHarness, "prove", 2,
          "delay source: R within 0 … 2^L − 2 (mseq), 0 … 2^Wm − 1 (masked), 0 (off); "
          "its registers never hold zero (L 2 … 32, Wm 1 … 16)",
          mutant=lambda: SourceHarness(_OffByOneSource)),
    Proof("delay_core.lfsr_fixed", lambda: LfsrHarness(length=5, steps=3), "prove", 1,
          "LFSR (L = 5, 3 steps per advance): never zero, nothing above bit L − 1",
          mutant=lambda: LfsrHarness(_zero_loading, length=5)),
    Proof("delay_core.lfsr_runtime", LfsrHarness, "prove", 1,
          "LFSR (run-time L): never zero, nothing above bit L − 1 of the loaded L",
          mutant=lambda: LfsrHarness(_zero_loading)),
]
