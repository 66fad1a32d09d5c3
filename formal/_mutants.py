"""Broken blocks of the delay core, for the mutants of ``formal/delay_core.py`` and
``formal/delay_blocks.py``: wrappers with the signature of the block they wrap, blocks that
override some of their own statements, or, for the LFSR, a register without its zero guard."""

from amaranth.hdl import Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from ..hdl.delay.source import DelaySource
from ..hdl.delay.laser import LaserTrigger
from ..hdl.delay.lfsr import POLYNOMIALS, _galois_step
from ..hdl.delay.scheduler import PulseScheduler, _Timer

from ._harness import assigned


def _past(m, value):
    """``value`` in the previous cycle (its initial value in the first)."""
    past = Signal.like(value, name="past")
    m.d.sync += past.eq(value)
    return past


class _Wrapper(wiring.Component):
    def __init__(self, inner):
        self.inner = inner
        super().__init__(inner.signature)

    def forward(self, m, **replace):
        """Connect every port to the inner block's, but those in ``replace`` (name -> value
        driven into the inner block's input, or out of the wrapper's output)."""
        m.submodules.inner = inner = self.inner
        for name, member in self.signature.members.items():
            outer, block = getattr(self, name), getattr(inner, name)
            if name == "delays" and member.flow == In:
                # (always valid: `valid` is a constant)
                m.d.comb += [block.payload.eq(replace.get("payload", outer.payload)),
                             outer.ready.eq(block.ready)]
            elif name == "delays":
                m.d.comb += [outer.payload.eq(block.payload), block.ready.eq(outer.ready)]
            elif member.flow == In:
                m.d.comb += block.eq(replace.get(name, outer))
            else:
                m.d.comb += outer.eq(replace.get(name, block))
        return m


class _LateStartTrigger(_Wrapper):
    """The TDC start one cycle after the laser's rising edge."""

    def __init__(self, *, width_bits):
        super().__init__(LaserTrigger(width_bits=width_bits))

    def elaborate(self, platform):
        m = Module()
        return self.forward(m, tdc_start=_past(m, self.inner.tdc_start))


class _RuntTrigger(_Wrapper):
    """Laser pulses a cycle short."""

    def __init__(self, *, width_bits):
        super().__init__(LaserTrigger(width_bits=width_bits))

    def elaborate(self, platform):
        return self.forward(Module(), width=self.width - 1)


class _NoDelayScheduler(_Wrapper):
    """Fires as if every delay were zero (and still reports it in ``fire_delay``)."""

    def __init__(self, **kwargs):
        super().__init__(PulseScheduler(**kwargs))

    def elaborate(self, platform):
        m = Module()
        payload = Signal.like(self.delays.payload)
        m.d.comb += [payload.eq(self.delays.payload), payload.zero.eq(1),
                     payload.zero_late.eq(0)]
        return self.forward(m, payload=payload)


class _LongPeriodScheduler(_Wrapper):
    """Takes every period a cycle long."""

    def __init__(self, **kwargs):
        super().__init__(PulseScheduler(**kwargs))

    def elaborate(self, platform):
        m = Module()
        settings = Signal.like(self.settings)
        m.d.comb += [settings.eq(self.settings), settings.period.eq(self.settings.period + 1)]
        return self.forward(m, settings=settings)


class _LateStopScheduler(_Wrapper):
    """Stops a cycle after ``enable`` falls."""

    def __init__(self, **kwargs):
        super().__init__(PulseScheduler(**kwargs))

    def elaborate(self, platform):
        m = Module()
        return self.forward(m, enable=self.enable | _past(m, self.enable))


class _EagerWidthScheduler(_Wrapper):
    """Applies a new pulse width in the ``update`` cycle, in the middle of a frame."""

    def __init__(self, **kwargs):
        super().__init__(PulseScheduler(**kwargs))

    def elaborate(self, platform):
        m = Module()
        return self.forward(m, fire_width=Mux(self.update, self.settings.pulse_width,
                                              self.inner.fire_width))


class _OffByOneSource(_Wrapper):
    """``mseq`` delays ``R + 1``: the register state rather than ``state - 1``."""

    def __init__(self, **kwargs):
        super().__init__(DelaySource(**kwargs))

    def elaborate(self, platform):
        m = Module()
        m = self.forward(m)
        m.d.comb += self.delays.payload.value.eq(self.inner.delays.payload.value + 1)
        return m


class _ZeroLoadingLfsr(wiring.Component):
    """An LFSR (one step per advance) that loads a zero seed as it is."""

    def __init__(self, *, length=None):
        self._length = length
        members = {"seed": In(32), "load": In(1), "advance": In(1), "state": Out(32)}
        if length is None:
            members["length"] = In(range(2, 33))
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        taps = POLYNOMIALS[self._length or 32] >> 1
        mask = (1 << (self._length or 32)) - 1
        state = Signal(32, init=1)
        m.d.comb += self.state.eq(state)
        with m.If(self.load):
            m.d.sync += state.eq(self.seed & mask)
        with m.Elif(self.advance):
            m.d.sync += state.eq(_galois_step(state, taps))
        return m


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
