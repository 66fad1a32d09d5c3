from amaranth.hdl import *
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from . import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles
from .delay import DelayMode, DelaySource, DELAY_WIDTH, MAX_MASK_WIDTH
from .lfsr import MAX_LENGTH
from .scheduler import PulseScheduler, PERIOD_WIDTH, PULSE_WIDTH_WIDTH, check_widths
from .laser import LaserTrigger


__all__ = ["DelayCore"]


class DelayCore(wiring.Component):
    """FLISS delay core: delay source, pulse scheduler and laser trigger.

    Every setting is a run-time input; see :class:`PulseScheduler` for when settings take effect.

    Parameters
    ----------
    clock_hz : int
        System clock frequency in Hz. It sets nothing in the logic: all settings are in cycles.
        It is kept as :attr:`clock_hz` for tools that convert to and from seconds.
    period_width, pulse_width_width : int
        Widths of the ``period`` and ``pulse_width`` settings, in bits
        (:func:`~fliss.hdl.scheduler.check_widths`).

    Members
    -------
    enable, update : In(1)
        Run, and sample new settings while running.
    mode : In(DelayMode)
    length : In(range(2, 33))
    mask_width : In(range(1, 17))
    seed : In(32)
        Delay source settings (:class:`DelaySource`).
    period : In(period_width)
    grid : In(1)
    pulse_width : In(pulse_width_width)
        Scheduler settings (:class:`PulseScheduler`).
    laser : Out(1)
    tdc_start : Out(1)
        Laser trigger and TDC start (:class:`LaserTrigger`).
    running : Out(1)
    fire : Out(1)
    fire_delay : Out(32)
    pulse_index : Out(32)
        Monitor outputs of the scheduler; ``fire`` leads ``tdc_start`` by one cycle.
    """

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, period_width=PERIOD_WIDTH,
                 pulse_width_width=PULSE_WIDTH_WIDTH):
        period_cycles(clock_hz, DEFAULT_PRF_HZ)  # validates the clock
        check_widths(period_width, pulse_width_width)
        self.clock_hz = clock_hz
        self.period_width = period_width
        self.pulse_width_width = pulse_width_width
        super().__init__({
            "enable":      In(1),
            "update":      In(1),
            "mode":        In(DelayMode),
            "length":      In(range(2, MAX_LENGTH + 1)),
            "mask_width":  In(range(1, MAX_MASK_WIDTH + 1)),
            "seed":        In(MAX_LENGTH),
            "period":      In(period_width),
            "grid":        In(1),
            "pulse_width": In(pulse_width_width),
            "laser":       Out(1),
            "tdc_start":   Out(1),
            "running":     Out(1),
            "fire":        Out(1),
            "fire_delay":  Out(DELAY_WIDTH),
            "pulse_index": Out(32),
        })

    def elaborate(self, platform):
        m = Module()

        m.submodules.source = source = DelaySource()
        m.submodules.scheduler = scheduler = PulseScheduler(
            period_width=self.period_width, pulse_width_width=self.pulse_width_width)
        m.submodules.trigger = trigger = LaserTrigger(width_bits=self.pulse_width_width)

        wiring.connect(m, source.delays, scheduler.delays)
        m.d.comb += [
            source.mode.eq(self.mode),
            source.length.eq(self.length),
            source.mask_width.eq(self.mask_width),
            source.seed.eq(self.seed),
            source.load.eq(scheduler.reload),
            scheduler.delay_kind.eq(source.kind),
            scheduler.delay_zero.eq(source.zero),
            scheduler.delay_zero_late.eq(source.zero_late),
            scheduler.delay_wide.eq(source.wide),
            scheduler.delay_narrow.eq(source.narrow),

            scheduler.enable.eq(self.enable),
            scheduler.update.eq(self.update),
            scheduler.period.eq(self.period),
            scheduler.grid.eq(self.grid),
            scheduler.pulse_width.eq(self.pulse_width),

            trigger.fire.eq(scheduler.fire),
            trigger.width.eq(scheduler.fire_width),

            self.laser.eq(trigger.laser),
            self.tdc_start.eq(trigger.tdc_start),
            self.running.eq(scheduler.running),
            self.fire.eq(scheduler.fire),
            self.fire_delay.eq(scheduler.fire_delay),
            self.pulse_index.eq(scheduler.pulse_index),
        ]

        return m
