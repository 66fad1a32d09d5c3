"""Delay core: delay source, pulse scheduler and laser trigger."""

from amaranth.hdl import Module
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from ..clock import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles
from .source import DelaySource
from .keyed import Keying
from .laser import LaserTrigger
from ..registers import DelaySettings
from .scheduler import PulseScheduler
from .settings import DELAY_WIDTH, IV_BITS, PERIOD_WIDTH, PULSE_WIDTH_WIDTH, check_widths


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
        (:func:`~fliss.hdl.delay.settings.check_widths`).
    keyed : bool
        Build the ``keyed`` delay source (:class:`DelaySource` ``keyed``).

    Members
    -------
    enable, update : In(1)
        Run, and sample new settings while running.
    settings : In(DelaySettings(period_width=..., pulse_width_width=...))
        Delay source settings (``mode``, ``length``, ``mask_width``, ``seed``:
        :class:`DelaySource`) and scheduler settings (``period``, ``grid``, ``pulse_width``:
        :class:`PulseScheduler`).
    laser : Out(1)
    tdc_start : Out(1)
        Laser trigger and TDC start (:class:`LaserTrigger`).
    running : Out(1)
    fire : Out(1)
    fire_delay : Out(32)
    pulse_index : Out(32)
        Monitor outputs of the scheduler; ``fire`` leads ``tdc_start`` by one cycle.
    keying : In(Keying)
    rekey : In(1)
    iv : Out(80)
        Key and IV of the ``keyed`` source, their write strobe, and the IV in use (only if
        ``keyed``; see :class:`DelaySource`). In ``keyed`` mode a run starts only once the
        source has a delay in hand, at most :data:`~fliss.hdl.delay.settings.KEYED_START_CYCLES`
        after the load that initialises it; an ``update`` that initialises it stops the run
        until then, and it starts again (``pulse_index`` from 0).
    """

    def __init__(self, *, clock_hz=DEFAULT_CLOCK_HZ, period_width=PERIOD_WIDTH,
                 pulse_width_width=PULSE_WIDTH_WIDTH, keyed=True):
        period_cycles(clock_hz, DEFAULT_PRF_HZ)  # validates the clock
        check_widths(period_width, pulse_width_width)
        self.clock_hz = clock_hz
        self.period_width = period_width
        self.pulse_width_width = pulse_width_width
        if not isinstance(keyed, bool):
            raise TypeError(f"keyed must be True or False, not {keyed!r}")
        self.keyed = keyed
        keying = dict(keying=In(Keying), rekey=In(1), iv=Out(IV_BITS)) if keyed else {}
        super().__init__({
            "enable":      In(1),
            "update":      In(1),
            "settings":    In(DelaySettings(period_width=period_width,
                                            pulse_width_width=pulse_width_width)),
            "laser":       Out(1),
            "tdc_start":   Out(1),
            "running":     Out(1),
            "fire":        Out(1),
            "fire_delay":  Out(DELAY_WIDTH),
            "pulse_index": Out(32),
            **keying,
        })

    def elaborate(self, platform):
        m = Module()

        m.submodules.source = source = DelaySource(layout=self.settings.shape(),
                                                   keyed=self.keyed)
        m.submodules.scheduler = scheduler = PulseScheduler(
            period_width=self.period_width, pulse_width_width=self.pulse_width_width)
        m.submodules.trigger = trigger = LaserTrigger(width_bits=self.pulse_width_width)

        wiring.connect(m, source.delays, scheduler.delays)
        m.d.comb += [
            source.settings.eq(self.settings),
            source.load.eq(scheduler.reload),

            scheduler.settings.eq(self.settings),
            scheduler.update.eq(self.update),

            trigger.fire.eq(scheduler.fire),
            trigger.width.eq(scheduler.fire_width),

            self.laser.eq(trigger.laser),
            self.tdc_start.eq(trigger.tdc_start),
            self.running.eq(scheduler.running),
            self.fire.eq(scheduler.fire),
            self.fire_delay.eq(scheduler.fire_delay),
            self.pulse_index.eq(scheduler.pulse_index),
        ]
        if self.keyed:
            m.d.comb += [
                source.keying.eq(self.keying),
                source.rekey.eq(self.rekey),
                self.iv.eq(source.iv),
            ]

        # A run starts only once the last pulse of the one before has ended: after a stop and
        # a quick restart, the new run's first pulse would otherwise fire into it and merge with
        # it (found by the formal proof `delay_core.pulses`). A running scheduler is not held,
        # except by the keyed source while it initialises (from an update).
        m.d.comb += scheduler.enable.eq(self.enable & (scheduler.running | ~trigger.laser) &
                                        ~source.busy)

        return m
