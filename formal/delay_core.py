"""Formal harness of the delay core (``hdl/delay/core.py``): laser trigger, pulse scheduler and
delay source wired together, and the small settings every delay harness shares (the blocks alone
are in ``formal/delay_blocks.py``).

The core is proved with small settings, as the register file would accept them: ``period`` from
2 to :data:`MAX_PERIOD` (a 17-bit ``period``, the narrowest the scheduler takes), a 3-bit
``pulse_width`` from 1 to ``period - 1``, register lengths ``L`` up to :data:`MAX_L` and mask
widths ``Wm`` up to :data:`MAX_WM`; in ``grid`` mode the largest delay (of the table of modes,
:mod:`fliss.hdl.delay.modes`) plus the pulse width is below the period. ``enable`` and
``update`` are free in every cycle.

Mutants swap a block of the core for a broken one (``formal/_mutants.py``) while the core
elaborates (:class:`_ProbedCore`).
"""

from amaranth.hdl import Assert, Assume, Cat, Cover, Const, Module, Mux, ResetSignal, Signal, Value
from amaranth.hdl._ast import AnySeq
from amaranth.lib import wiring
from amaranth.lib.wiring import In

import fliss.hdl.delay.core as core_module
from ..hdl.delay.core import DelayCore
from ..hdl.delay.modes import MODES, DelayMode
from ..hdl.registers import DelaySettings

from ._abstract import elaborate_with_free_trivium
from ._harness import past
from ._mutants import (_EagerWidthScheduler, _LateStartTrigger, _LateStopScheduler,
                       _LiveSettingsSource, _LongPeriodScheduler, _MidFramePeriodScheduler,
                       _NoDelayScheduler, _RuntTrigger)
from .runner import Proof


__all__ = ["PERIOD_WIDTH", "PULSE_WIDTH_WIDTH", "MAX_PERIOD", "MAX_L", "MAX_WM", "SETTINGS",
           "max_delay", "assume_valid", "CoreHarness", "PROOFS"]


#: Small settings of the core harness.
PERIOD_WIDTH, PULSE_WIDTH_WIDTH, MAX_PERIOD, MAX_L, MAX_WM = 17, 3, 10, 3, 2
SETTINGS = DelaySettings(period_width=PERIOD_WIDTH, pulse_width_width=PULSE_WIDTH_WIDTH)


def max_delay(m, mode, sizes, name, *, keyed=False):
    """The largest delay of ``mode`` (of :data:`~fliss.hdl.delay.modes.MODES`, with its size
    settings' values in ``sizes``: name -> value) as a 33-bit signal named ``name``; the keyed
    mode reads 0 unless ``keyed``."""
    largest = Signal(33, name=name)
    with m.Switch(mode):
        for row in MODES.values():
            if row.size is not None and (keyed or not row.keyed):
                with m.Case(row.mode):
                    m.d.comb += largest.eq((Const(1, 33) << sizes[row.size]) - row.less)
    return largest


def assume_valid(m, settings, *, max_l=MAX_L, max_wm=MAX_WM, keyed=False):
    """Settings the register file accepts, small (and not keyed, unless ``keyed``)."""
    largest = max_delay(m, settings.mode, {"length": settings.length,
                                           "mask_width": settings.mask_width}, "max_delay",
                        keyed=keyed)
    if not keyed:
        m.d.comb += Assume(settings.mode.as_value() != DelayMode.KEYED.value)
    m.d.comb += [
        Assume((settings.length >= 2) & (settings.length <= max_l)),
        Assume((settings.mask_width >= 1) & (settings.mask_width <= max_wm)),
        Assume((settings.period >= 2) & (settings.period <= MAX_PERIOD)),
        Assume((settings.pulse_width >= 1) & (settings.pulse_width < settings.period)),
        Assume(~settings.grid | (largest + settings.pulse_width < settings.period)),
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
    property asserted. ``fixed`` settings stay put while running, and ``update`` stays low.
    ``keyed``: the keyed mode is allowed too, with the key, IV and their write strobe free in
    every cycle and the keyed source's Trivium abstracted (``formal/_abstract.py``: its
    readiness and keystream free in every cycle)."""

    enable:   In(1)
    update:   In(1)
    settings: In(SETTINGS)

    def __init__(self, check, *, swaps=None, fixed=False, keyed=False):
        self.check = check
        self.swaps = swaps
        self.fixed = fixed
        self.keyed = keyed
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        core = _ProbedCore(self.swaps)
        if self.keyed:
            m.submodules.core = elaborate_with_free_trivium(core, platform)
            m.d.comb += [core.keying.eq(AnySeq(len(core.keying.as_value()))),
                         core.rekey.eq(AnySeq(1))]
        else:
            m.submodules.core = core
        m.d.comb += [core.enable.eq(self.enable), core.update.eq(self.update),
                     core.settings.eq(self.settings)]
        m.d.comb += Assume(~ResetSignal())
        assume_valid(m, self.settings, keyed=self.keyed)
        enable_d = past(m, self.enable)
        if self.fixed:
            settings_d = past(m, self.settings)
            m.d.comb += [Assume(~self.update), Assume(~core.running | (self.settings == settings_d))]

        laser_d = past(m, core.laser)
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

        if self.keyed:      # (the keyed mode reached, its delays and the start's wait)
            keyed_fire = core.fire & fired & (self.settings.mode.as_value() == DelayMode.KEYED)
            m.d.comb += Cover(keyed_fire & (core.fire_delay > 0))
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
            take_d = past(m, core.take)
            with m.If(core.take):
                m.d.sync += [width.eq(Mux(pending, pending_width, width)), pending.eq(0)]
            with m.If(~core.running | self.update):
                m.d.sync += [pending.eq(1), pending_width.eq(self.settings.pulse_width)]
            width_d = past(m, core.fire_width)
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
        fire_delay_d = past(m, core.fire_delay)
        take_d = past(m, core.take)
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


def _core(check, depth, doc, swaps, *, fixed=False, mode="bmc", cover_depth=None):
    return Proof(f"delay_core.{check}", lambda: CoreHarness(check, fixed=fixed), mode, depth,
                 doc, mutant=lambda: CoreHarness(check, fixed=fixed, swaps=swaps),
                 cover_depth=cover_depth)


PROOFS = [
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
]
