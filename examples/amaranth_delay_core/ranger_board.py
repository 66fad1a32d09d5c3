"""The range finder on a board: its pins, and the board's button stepping through preset delay
settings written into the user's registers.

The ports are plain signals named after the pins of FLISS's board top level
(``fliss.boards.BoardTop``: ``laser``, ``tdc_start``, ``photon`` on the PMOD pins of
``docs/boards.md``, ``led`` and ``button`` on the board), so ``build_icebreaker.py`` builds it
for the iCEBreaker; with a platform of your own, request the pins and connect them instead.
"""

import math

from amaranth.hdl import Cat, Module, Signal
from amaranth.lib import cdc, wiring
from amaranth.lib.wiring import In, Out

from fliss.hdl.delay import DelayMode

from ranger import Ranger
from ranger_presets import PresetWriter


__all__ = ["DEBOUNCE_S", "presets", "default_registers", "RangerOnBoard"]


#: The button is sampled at least this many seconds apart (longer than its contacts bounce).
DEBOUNCE_S = 0.02


def presets(clock_hz):
    """The delay settings the button steps through, for a clock of ``clock_hz``: pulses 2 cycles
    wide at a nominal 1 MHz (at least 40 cycles apart), delayed by an m-sequence of length 5
    (0 to 30 cycles; the settings after reset); in grid mode by 4-bit masked delays, at 0.8 MHz;
    not delayed."""
    period = max(40, round(clock_hz / 1e6))
    common = dict(length=5, mask_width=4, grid=0, pulse_width=2, period=period)
    return [
        {**common, "mode": DelayMode.MSEQ.value, "seed": 1},
        {**common, "mode": DelayMode.MASKED.value, "seed": 0xACE1, "grid": 1,
         "period": round(period * 1.25)},
        {**common, "mode": DelayMode.OFF.value, "seed": 1},
    ]


def default_registers(clock_hz):
    """Register values after reset: running, the first of :func:`presets`, and a window of 10
    to 20 TDC cycles."""
    return dict(enable=1, **presets(clock_hz)[0], window_start=10, window_end=20)


class RangerOnBoard(wiring.Component):
    """:class:`~ranger.Ranger` with :func:`default_registers`; each press of ``button`` writes
    the next of :func:`presets` into its registers (:class:`~ranger_presets.PresetWriter`).

    Parameters
    ----------
    clock_hz : int
        Clock frequency in Hz: the presets' periods and the button's sampling.
    debounce_s : float
        Least time between two samples of the button, in seconds.

    Members
    -------
    photon, button : In(1)
        Photon detector and the board's button, asynchronous.
    laser, tdc_start : Out(1)
        The delay core's laser trigger and TDC start.
    led : Out(2)
        Running; the last photon was within the window.
    """

    photon:    In(1)
    button:    In(1)
    laser:     Out(1)
    tdc_start: Out(1)
    led:       Out(2)

    def __init__(self, clock_hz, *, debounce_s=DEBOUNCE_S):
        self.clock_hz = clock_hz
        self.debounce_s = debounce_s
        self.ranger = Ranger(clock_hz, default_registers(clock_hz))
        self.presets = PresetWriter(presets(clock_hz))
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        m.submodules.ranger = ranger = self.ranger
        m.submodules.presets = writer = self.presets

        # Button: sampled every 2**debounce_bits cycles (as long as its contacts bounce, or
        # longer); a press is a sample high after a sample low
        pressed = Signal()
        m.submodules.button_sync = cdc.FFSynchronizer(self.button, pressed)
        debounce_bits = max(1, math.ceil(math.log2(self.debounce_s * self.clock_hz)))
        prescaler = Signal(debounce_bits)
        sample = Signal()
        m.d.sync += Cat(prescaler, sample).eq(prescaler + 1)
        sampled = Signal()
        with m.If(sample):
            m.d.sync += sampled.eq(pressed)

        # A press writes the next preset
        m.d.comb += writer.step.eq(sample & pressed & ~sampled)
        wiring.connect(m, writer.write, ranger.write)

        # Pins
        m.d.comb += [
            ranger.photon.eq(self.photon),
            self.laser.eq(ranger.laser),
            self.tdc_start.eq(ranger.tdc_start),
            self.led.eq(Cat(ranger.running, ranger.near)),
        ]

        return m
