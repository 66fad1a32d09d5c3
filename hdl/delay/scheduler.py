from amaranth.hdl import Cat, Elaboratable, Module, Mux, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from .source import Delay
from ..registers import DelaySettings
from .settings import DELAY_WIDTH, PERIOD_WIDTH, PULSE_WIDTH_WIDTH, check_widths


__all__ = ["PERIOD_WIDTH", "PULSE_WIDTH_WIDTH", "check_widths", "DELAY_ZERO", "DELAY_WIDE",
           "DELAY_NARROW", "PulseScheduler"]


#: Kinds of delay (:class:`~fliss.hdl.delay.source.Delay` ``kind``): always zero; ``wide = R + 1``;
#: ``narrow = R``.
DELAY_ZERO, DELAY_WIDE, DELAY_NARROW = 0, 1, 2


class PulseScheduler(wiring.Component):
    """Pulse scheduler.

    Cuts time into frames, one laser pulse per frame. At the first cycle of frame ``k`` (its
    *take* cycle ``b[k]``) it takes a delay ``R[k]`` from ``delays``; the pulse fires at
    ``b[k] + 1 + R[k]``. The next frame begins at

    * ``b[k] + T + R[k]`` in ``interval`` mode (``grid`` low): consecutive pulses are ``T + R``
      apart, equation 3 of the paper;
    * ``b[k] + T`` in ``grid`` mode: pulse ``k`` fires at ``k T + R[k]`` after the start, so the
      effective PRF equals the nominal PRF. This needs ``max(R) + pulse_width < T``.

    Acquisition starts in the cycle after ``enable`` rises (``b[0]``) and stops as soon as
    ``enable`` falls; a pulse already firing completes in the laser trigger.

    Settings are sampled in every cycle while stopped, and on ``update`` while running. Sampled
    settings apply from the first frame whose take cycle comes after the ``update`` cycle; that
    frame also restarts the delay sequence from its seed (``reload`` is asserted on ``update``).
    A setting therefore never changes in the middle of a frame: no pulse is cut short, merged or
    doubled, provided that ``pulse_width < period`` (and the ``grid`` condition above), which the
    register file enforces (a design without it checks them with
    :func:`~fliss.hdl.delay.modes.delay_problems`).

    Parameters
    ----------
    period_width, pulse_width_width : int
        Widths of the ``period`` and ``pulse_width`` settings, in bits (:func:`check_widths`);
        narrower settings make a smaller scheduler.

    Members
    -------
    enable : In(1)
        Run.
    update : In(1)
        Sample the settings while running.
    settings : In(DelaySettings(period_width=..., pulse_width_width=...))
        Of the delay core's settings, the scheduler uses ``period`` (nominal period ``T`` in
        clock cycles, at least 2), ``grid`` (``grid`` mode when high, ``interval`` mode when
        low) and ``pulse_width`` (laser pulse width in clock cycles, passed on with each pulse).
    delays : In(stream.Signature(Delay, always_valid=True))
        Delays in clock cycles, one taken per frame. The pulse is timed from the hints of the
        payload (:class:`~fliss.hdl.delay.source.Delay`: the kind of delay, ``R == 0``, ``R + 1`` or
        ``R``), so the delays must come from a :class:`~fliss.hdl.delay.source.DelaySource`; its
        ``value`` only gives ``fire_delay``.
    reload : Out(1)
        Restart the delay sequence from its seed (to :class:`~.source.DelaySource` ``load``).
    running : Out(1)
        Acquisition is running.
    fire : Out(1)
        Fire a laser pulse in this cycle.
    fire_width : Out(pulse_width_width)
        Width of the pulse fired in this cycle.
    fire_delay : Out(32)
        Delay ``R`` of the pulse fired in this cycle.
    pulse_index : Out(32)
        Number of pulses fired since the start; the index of the pulse fired in this cycle.

    Takes are at least two cycles apart (``period >= 2``): the take cycle is predicted a cycle
    ahead, and the timers are split in 16-bit halves; a period below 2 is not supported.
    """

    def __init__(self, *, period_width=PERIOD_WIDTH, pulse_width_width=PULSE_WIDTH_WIDTH):
        check_widths(period_width, pulse_width_width)
        self.period_width = period_width
        self.pulse_width_width = pulse_width_width
        super().__init__({
            "enable":      In(1),
            "update":      In(1),
            "settings":    In(DelaySettings(period_width=period_width,
                                            pulse_width_width=pulse_width_width)),
            "delays":      In(stream.Signature(Delay, always_valid=True)),
            "reload":      Out(1),
            "running":     Out(1),
            "fire":        Out(1),
            "fire_width":  Out(pulse_width_width),
            "fire_delay":  Out(DELAY_WIDTH),
            "pulse_index": Out(32),
        })

    def elaborate(self, platform):
        m = Module()
        settings = self.settings
        delay = self.delays.payload

        # Settings: `pending` holds settings sampled on update, `active` those of the current frame.
        # The period is kept with the flags the frame timer needs when it loads it.
        pending         = Signal()
        pending_period  = Signal(self.period_width)
        pending_flags   = Signal(4)
        pending_grid    = Signal()
        pending_width   = Signal(self.pulse_width_width)
        active_period   = Signal(self.period_width)
        active_flags    = Signal(4)
        active_grid     = Signal()
        active_width    = Signal(self.pulse_width_width)

        sample = Signal()
        m.d.comb += sample.eq(~self.running | self.update)
        with m.If(sample):
            m.d.sync += [
                pending.eq(1),
                pending_period.eq(settings.period),
                pending_flags.eq(_Timer.flags(settings.period, target=2)),
                pending_grid.eq(settings.grid),
                pending_width.eq(settings.pulse_width),
            ]
        m.d.comb += self.reload.eq(sample)

        # Take cycle of each frame, predicted a cycle early
        take = Signal()
        take_d = Signal()
        m.d.comb += self.delays.ready.eq(take)
        m.d.sync += take_d.eq(take)

        with m.If(take):
            m.d.sync += [
                active_period.eq(Mux(pending, pending_period, active_period)),
                active_flags.eq(Mux(pending, pending_flags, active_flags)),
                active_grid.eq(Mux(pending, pending_grid, active_grid)),
                active_width.eq(Mux(pending, pending_width, active_width)),
                self.fire_delay.eq(delay.value),
            ]
            with m.If(~self.update):
                m.d.sync += pending.eq(0)

        # Pulse timers: the pulse fires `R` cycles after the cycle after the take cycle. `due` is
        # high in that cycle. Delays come with hints from the source, for a fast start: the kind
        # of delay, `R == 0`, and a value to count: `R + 1` (`WIDE`, up to 32 bits) or `R`
        # (`NARROW`, up to 16 bits).
        armed = Signal()    # the pulse of this frame has not fired yet
        due = Signal()      # the pulse of this frame is due in this cycle, from the timers
        pulse = Signal()    # the pulse of this frame fires in this cycle (unless stopped)
        kind = Signal(len(delay.kind))      # `kind` of this frame's delay
        narrow = Signal(16)
        m.submodules.wide = wide = _Timer(DELAY_WIDTH, target=1)
        m.d.comb += [
            wide.load.eq(take),
            wide.clear.eq(pulse),
            wide.value.eq(delay.wide),
            wide.value_flags.eq(_Timer.flags(delay.wide, target=1)),
        ]
        with m.If(take):
            m.d.sync += [
                kind.eq(delay.kind),
                narrow.eq(delay.narrow),
            ]
        with m.Else():
            m.d.sync += narrow.eq(narrow - 1)
        counted = Mux(kind == DELAY_WIDE, wide.done_next, narrow == 1)
        m.d.comb += pulse.eq(due | delay.zero_late)
        m.d.sync += [
            due.eq(Mux(take, delay.zero, armed & counted)),
            armed.eq(Mux(take, ~delay.zero, armed & ~pulse)),
        ]

        # Frame timer: the next take cycle is `T` cycles after the take cycle (`grid`), or
        # `T - 1` cycles after the pulse (`interval`). It is loaded with `T` in the cycle after
        # the take cycle, or in the pulse's cycle, and counts `T - 1` cycles.
        m.submodules.frame = frame = _Timer(self.period_width, target=2)
        m.d.comb += [
            # (not in a stop: a load would outlast the clear, into a restart a cycle later)
            frame.load.eq(Mux(active_grid, take_d, pulse) & self.running & self.enable),
            frame.clear.eq(take | ~self.running | ~self.enable),
            frame.value.eq(active_period),
            frame.value_flags.eq(active_flags),
        ]

        with m.If(~self.running):
            with m.If(self.enable):
                m.d.sync += [
                    self.running.eq(1),
                    take.eq(1),
                ]
        with m.Elif(~self.enable):
            m.d.sync += [
                self.running.eq(0),
                take.eq(0),
                armed.eq(0),
                due.eq(0),
            ]
        with m.Else():
            m.d.sync += take.eq(frame.done_next)

        # Pulse
        m.d.comb += [
            self.fire.eq(self.running & self.enable & pulse),
            self.fire_width.eq(active_width),
        ]

        # Pulse index: `next_index` is one ahead, its high half a cycle late (pulses are at least
        # two cycles apart).
        next_lo = Signal(16)
        next_hi = Signal(16)
        carry = Signal()
        with m.If(~self.running & self.enable):
            m.d.sync += [
                self.pulse_index.eq(0),
                next_lo.eq(1),
                next_hi.eq(0),
                carry.eq(0),
            ]
        with m.Else():
            m.d.sync += [
                next_hi.eq(next_hi + carry),
                carry.eq(0),
            ]
            with m.If(self.fire):
                m.d.sync += [
                    self.pulse_index.eq(Cat(next_lo, next_hi)),
                    Cat(next_lo, carry).eq(next_lo + 1),
                ]

        return m


class _Timer(Elaboratable):
    """Down counter in two 16-bit halves, for the scheduler's long timers.

    Loaded with ``value`` in cycle ``t0``, it holds ``value - j + 1`` in cycle ``t0 + j``;
    ``done_next`` is high in the cycle before it holds ``target``, from the load until ``clear``.
    The high half borrows a cycle after the low half reaches zero, from a registered flag, and
    every comparison is made a cycle ahead into a register, so that no path goes through more
    than one 16-bit carry chain or one comparison. ``value_flags`` are :meth:`flags` of the
    value, computed ahead by the user.
    """

    def __init__(self, width, *, target):
        assert 0 <= target and target + 2 < (1 << 16)
        self.target = target
        self.load = Signal()
        self.clear = Signal()
        self.value = Signal(width)
        self.value_flags = Signal(4)
        self.done_next = Signal()

    @staticmethod
    def flags(value, *, target):
        lo, hi = value[:16], value[16:]
        return Cat(lo == 0, lo == target + 1, hi == 0, value == target)

    def elaborate(self, platform):
        m = Module()

        lo = Signal(16)
        hi = Signal(len(self.value) - 16)
        lo_zero = Signal()      # lo == 0: the high half borrows in this cycle
        lo_near = Signal()      # lo == target + 1 (and armed)
        hi_zero = Signal()      # hi == 0
        armed = Signal()

        armed_next = self.load | (armed & ~self.clear)
        m.d.sync += armed.eq(armed_next)
        with m.If(self.load):
            m.d.sync += [
                lo.eq(self.value[:16]),
                hi.eq(self.value[16:]),
                lo_zero.eq(self.value_flags[0]),
                lo_near.eq(self.value_flags[1]),
                hi_zero.eq(self.value_flags[2]),
            ]
        with m.Else():
            m.d.sync += [
                lo.eq(lo - 1),
                hi.eq(hi - lo_zero),
                lo_zero.eq(lo == 1),
                lo_near.eq(armed_next & (lo == self.target + 2)),
                hi_zero.eq(Mux(lo_zero, hi == 1, hi_zero)),
            ]
        m.d.comb += self.done_next.eq(Mux(self.load, self.value_flags[3], hi_zero & lo_near))

        return m
