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

    The block to reuse in a design of your own: it fires a laser trigger once per frame, each
    pulse delayed by a pseudorandom number of clock cycles, and strobes ``tdc_start`` with each
    laser edge, so that a TDC started by it measures the time of flight with the delay cancelled
    (equation 5 of the paper). One clock domain (``sync``), no I/O buffers; ``laser`` and
    ``tdc_start`` come straight from flip-flops. ``examples/amaranth_delay_core/`` is a top level of a user's own around it.

    Timing, in cycles of the ``sync`` clock: ``enable`` rising in cycle ``e`` (the core stopped
    and the laser low) makes cycle ``e + 1`` the first frame's take cycle ``b[0]``; pulse ``k``
    is fired (``fire``) in cycle ``b[k] + 1 + R[k]``, ``R[k]`` its delay; ``laser`` is high in
    cycles ``fire + 1 … fire + pulse_width`` and ``tdc_start`` is high in cycle ``fire + 1``
    alone. The next take cycle is ``b[k] + period + R[k]`` (``grid`` low) or ``b[k] + period``
    (``grid`` high); see :class:`PulseScheduler`. :func:`fliss.sim.models.scheduler.simulate`
    gives these cycles bit for bit. ``enable`` falling stops the pulses at once (a pulse already
    on the laser completes); a restart waits until the laser is low.

    Settings are read every cycle while stopped, and on ``update`` while running; they apply
    from the next frame and restart the delay sequence from ``seed``. The core does not check
    them: give it settings within the limits below (:func:`~fliss.hdl.delay.modes.delay_problems`
    lists what is wrong with a set, as the FLISS register file refuses it); outside them the
    pulses are not those of the model.

    Parameters
    ----------
    clock_hz : int
        System clock frequency in Hz. It sets nothing in the logic: all settings are in cycles.
        It is kept as :attr:`clock_hz` for tools that convert to and from seconds.
    period_width, pulse_width_width : int
        Widths of the ``period`` and ``pulse_width`` settings, in bits: 17 to 32 and 1 to 16
        (:func:`~fliss.hdl.delay.settings.check_widths`; ``ValueError`` otherwise). Narrower
        settings make a smaller core.
    keyed : bool
        Build the ``keyed`` delay source (:class:`DelaySource` ``keyed``: the Trivium stream
        cipher, a large part of the core). Without it, mode ``KEYED`` gives zero delays.

    Members
    -------
    enable : In(1)
        Run while high.
    update : In(1)
        Sample ``settings`` while running (one-cycle strobe; the settings presented in that
        cycle apply from the next frame).
    settings : In(DelaySettings(period_width=..., pulse_width_width=...))
        A :class:`~fliss.hdl.registers.DelaySettings` struct; its fields and limits:

        * ``mode`` (:class:`~fliss.hdl.delay.modes.DelayMode`): ``OFF``, ``MSEQ``, ``MASKED``
          or ``KEYED`` (:class:`DelaySource`);
        * ``length`` (6 bits): register length ``L`` of ``MSEQ``, 2 to 32; delays
          ``0 … 2**L - 2``;
        * ``mask_width`` (5 bits): ``Wm`` of ``MASKED`` and ``KEYED``, 1 to 16; delays
          ``0 … 2**Wm - 1``;
        * ``seed`` (32 bits): non-zero; below ``2**L`` for ``MSEQ``;
        * ``period`` (``period_width`` bits): nominal period ``T`` in cycles, at least 2;
        * ``grid`` (1 bit): ``grid`` mode, which needs ``max delay + pulse_width < period``;
        * ``pulse_width`` (``pulse_width_width`` bits): laser pulse in cycles, 1 or more
          (0 acts as 1) and below ``period``.
    laser : Out(1)
        Laser trigger: high for ``pulse_width`` cycles per pulse.
    tdc_start : Out(1)
        TDC start strobe, one cycle, in the cycle of the laser's rising edge.
    running : Out(1)
        The scheduler runs (from the cycle after ``enable`` rises).
    fire : Out(1)
        A pulse fires in this cycle: it leads ``laser``'s rise and ``tdc_start`` by one cycle.
    fire_delay : Out(32)
        Delay ``R`` in cycles of the pulse fired (valid with ``fire``; held until the next).
    pulse_index : Out(32)
        Pulses fired since the start of the run: in the cycle of ``fire``, the index of the
        pulse fired (0 for the first); from the next cycle (that of ``tdc_start``) until the
        next pulse, one more, so ``pulse_index - 1`` is the index of the last pulse. Wraps
        around at ``2**32``.
    keying : In(Keying)
    rekey : In(1)
    iv : Out(80)
    spent : Out(1)
        Key and IV of the ``keyed`` source, their write strobe, the IV in use and whether every
        IV under the key is used (only if ``keyed``; see :class:`DelaySource`). In ``keyed``
        mode a run starts only once the source has a delay in hand, at most
        :data:`~fliss.hdl.delay.settings.KEYED_START_CYCLES` after the load that initialises it;
        an ``update`` that initialises it stops the run until then, and it starts again
        (``pulse_index`` from 0). A spent source never has one: no pulse fires in ``keyed``
        mode until a key is written.
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
        keying = dict(keying=In(Keying), rekey=In(1), iv=Out(IV_BITS),
                      spent=Out(1)) if keyed else {}
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
                self.spent.eq(source.spent),
            ]

        # A run starts only once the last pulse of the one before has ended: after a stop and
        # a quick restart, the new run's first pulse would otherwise fire into it and merge with
        # it (found by the formal proof `delay_core.pulses`). A running scheduler is not held,
        # except by the keyed source while it initialises (from an update).
        m.d.comb += scheduler.enable.eq(self.enable & (scheduler.running | ~trigger.laser) &
                                        ~source.busy)

        return m
