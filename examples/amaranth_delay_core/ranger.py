"""A user's own top level around the FLISS delay core: a range finder that tells whether a target
is within a window, its laser pulses delayed pseudorandomly so that other LiDARs' pulses do not
read as targets.

The delay core comes from FLISS (``fliss.hdl.delay``); the TDC (:mod:`ranger_tdc`) and the
register block (:mod:`ranger_registers`) are the user's own.
"""

from amaranth.hdl import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out

from fliss.hdl.delay import DelayCore

from ranger_registers import (PERIOD_WIDTH, PULSE_WIDTH_WIDTH, WINDOW_WIDTH, RangerRegisters,
                              RegisterWrite)
from ranger_tdc import CounterTdc, measurement_layout


__all__ = ["Ranger"]


class Ranger(wiring.Component):
    """Range finder: delay core, the user's registers and the user's TDC.

    The registers (:class:`~ranger_registers.RangerRegisters`) drive the delay core's
    ``enable``, ``update`` and ``settings``; the core's ``tdc_start`` starts the TDC
    (:class:`~ranger_tdc.CounterTdc`), which a photon on ``photon`` stops. Because the TDC starts
    with the delayed laser pulse, the echo of the ranger's own pulse is measured at its time of
    flight whatever the delay, while another LiDAR's pulses land at times that change from pulse
    to pulse. ``near`` says whether the last measurement was within the window.

    Parameters
    ----------
    clock_hz : int
        Clock frequency in Hz (kept by the delay core for tools that convert to seconds).
    reset : dict
        Register values after reset (:class:`~ranger_registers.RangerRegisters`).

    Members
    -------
    write : In(stream.Signature(RegisterWrite, always_ready=True))
        Register writes.
    photon : In(1)
        Photon detector, asynchronous.
    laser : Out(1)
        Laser trigger (the delay core's).
    tdc_start : Out(1)
        TDC start strobe (the delay core's), for a TDC outside too.
    running : Out(1)
        The delay core runs.
    measurements : Out(stream.Signature(measurement_layout(12), always_ready=True))
        Each photon measured: cycles from the TDC start, and the pulse index.
    near : Out(1)
        The last measurement was within ``window_start … window_end`` (inclusive).
    dropped : Out(16)
        Photons the TDC could not measure (:class:`~ranger_tdc.CounterTdc`).
    refused : Out(16)
        Register writes refused.
    """

    def __init__(self, clock_hz, reset):
        self.core = DelayCore(clock_hz=clock_hz, period_width=PERIOD_WIDTH,
                              pulse_width_width=PULSE_WIDTH_WIDTH, keyed=False)
        self.registers = RangerRegisters(reset)
        self.tdc = CounterTdc(width=WINDOW_WIDTH)
        super().__init__({
            "write":        In(stream.Signature(RegisterWrite, always_ready=True)),
            "photon":       In(1),
            "laser":        Out(1),
            "tdc_start":    Out(1),
            "running":      Out(1),
            "measurements": Out(stream.Signature(measurement_layout(WINDOW_WIDTH),
                                                 always_ready=True)),
            "near":         Out(1),
            "dropped":      Out(16),
            "refused":      Out(16),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.registers = registers = self.registers
        m.submodules.core = core = self.core
        m.submodules.tdc = tdc = self.tdc

        # Registers to the delay core
        wiring.connect(m, wiring.flipped(self.write), registers.write)
        m.d.comb += [
            core.enable.eq(registers.enable),
            core.update.eq(registers.update),
            core.settings.eq(registers.settings),
            self.refused.eq(registers.refused),
        ]

        # Delay core to the pins and the TDC
        m.d.comb += [
            self.laser.eq(core.laser),
            self.tdc_start.eq(core.tdc_start),
            self.running.eq(core.running),
            tdc.start.eq(core.tdc_start),
            tdc.hit.eq(self.photon),
            tdc.pulse_index.eq(core.pulse_index),
            self.dropped.eq(tdc.dropped),
        ]
        wiring.connect(m, tdc.measurements, wiring.flipped(self.measurements))

        # Window
        cycles = tdc.measurements.payload.cycles
        with m.If(tdc.measurements.valid):
            m.d.sync += self.near.eq((cycles >= registers.window_start) &
                                     (cycles <= registers.window_end))

        return m
