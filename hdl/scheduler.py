from amaranth.hdl import *
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from .delay import DELAY_WIDTH


__all__ = ["PERIOD_WIDTH", "PULSE_WIDTH_WIDTH", "PulseScheduler"]


#: Width of the period setting, in bits: down to 0.02 Hz at 80 MHz.
PERIOD_WIDTH = 32

#: Width of the laser pulse width setting, in bits.
PULSE_WIDTH_WIDTH = 16


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
    register file enforces.

    Members
    -------
    enable : In(1)
        Run.
    update : In(1)
        Sample the settings while running.
    period : In(32)
        Nominal period ``T`` in clock cycles, at least 2.
    grid : In(1)
        ``grid`` mode when high, ``interval`` mode when low.
    pulse_width : In(16)
        Laser pulse width in clock cycles, passed on with each pulse.
    delays : In(stream.Signature(32))
        Delays in clock cycles, one taken per frame.
    reload : Out(1)
        Restart the delay sequence from its seed (to :class:`DelaySource` ``load``).
    running : Out(1)
        Acquisition is running.
    fire : Out(1)
        Fire a laser pulse in this cycle.
    fire_width : Out(16)
        Width of the pulse fired in this cycle.
    fire_delay : Out(32)
        Delay ``R`` of the pulse fired in this cycle.
    pulse_index : Out(32)
        Number of pulses fired since the start; the index of the pulse fired in this cycle.
    """

    enable:      In(1)
    update:      In(1)
    period:      In(PERIOD_WIDTH)
    grid:        In(1)
    pulse_width: In(PULSE_WIDTH_WIDTH)
    delays:      In(stream.Signature(DELAY_WIDTH))
    reload:      Out(1)
    running:     Out(1)
    fire:        Out(1)
    fire_width:  Out(PULSE_WIDTH_WIDTH)
    fire_delay:  Out(DELAY_WIDTH)
    pulse_index: Out(32)

    def elaborate(self, platform):
        m = Module()

        # Settings: `pending` holds settings sampled on update, `active` those of the current frame
        pending         = Signal()
        pending_last    = Signal(PERIOD_WIDTH)   # period - 1
        pending_grid    = Signal()
        pending_width   = Signal(PULSE_WIDTH_WIDTH)
        active_last     = Signal(PERIOD_WIDTH)
        active_grid     = Signal()
        active_width    = Signal(PULSE_WIDTH_WIDTH)

        sample = Signal()
        m.d.comb += sample.eq(~self.running | self.update)
        with m.If(sample):
            m.d.sync += [
                pending.eq(1),
                pending_last.eq(self.period - 1),
                pending_grid.eq(self.grid),
                pending_width.eq(self.pulse_width),
            ]
        m.d.comb += self.reload.eq(sample)

        frame_last = Mux(pending, pending_last, active_last)
        frame_grid = Mux(pending, pending_grid, active_grid)
        frame_width = Mux(pending, pending_width, active_width)

        # Frame timer: cycles left in the current frame
        remaining = Signal(PERIOD_WIDTH + 1)
        take = Signal()
        m.d.comb += take.eq(self.running & (remaining == 0))

        # Pulse timer: cycles left until the pulse of the current frame fires
        armed = Signal()
        countdown = Signal(DELAY_WIDTH)

        with m.If(~self.running):
            with m.If(self.enable):
                m.d.sync += self.running.eq(1), self.pulse_index.eq(0)
        with m.Elif(~self.enable):
            m.d.sync += [
                self.running.eq(0),
                remaining.eq(0),
                armed.eq(0),
            ]
        with m.Else():
            with m.If(take):
                delay = self.delays.payload
                m.d.comb += self.delays.ready.eq(1)
                m.d.sync += [
                    remaining.eq(frame_last + Mux(frame_grid, 0, delay)),
                    countdown.eq(delay),
                    armed.eq(1),
                    self.fire_delay.eq(delay),
                    active_last.eq(frame_last),
                    active_grid.eq(frame_grid),
                    active_width.eq(frame_width),
                ]
                with m.If(~self.update):
                    m.d.sync += pending.eq(0)
            with m.Else():
                m.d.sync += remaining.eq(remaining - 1)
                with m.If(armed):
                    with m.If(countdown == 0):
                        m.d.sync += armed.eq(0)
                    with m.Else():
                        m.d.sync += countdown.eq(countdown - 1)

        # Pulse
        m.d.comb += [
            self.fire.eq(self.running & self.enable & armed & (countdown == 0)),
            self.fire_width.eq(active_width),
        ]
        with m.If(self.fire):
            m.d.sync += self.pulse_index.eq(self.pulse_index + 1)

        return m
