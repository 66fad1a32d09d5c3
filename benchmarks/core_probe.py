"""The delay core alone on a board, as the baseline of ``board_fmax.py`` and ``up5k_fit.py``.

Its settings are a shift register fed from a pin (``uart_rx``, one bit a cycle, no UART), so that
the synthesiser keeps all of the core: constant settings would fold most of it away. The button
is ``enable``; the bit shifted out of the top of the register is ``update``. It measures the pulse
path without the link side, the histogram and the TDC interfaces (docs/boards.md, "The delay core
on the UP5K").
"""

from amaranth.hdl import Cat, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.wiring import In, Out

from fliss.hdl.delay.core import DelayCore


__all__ = ["DelayCoreProbe"]


class DelayCoreProbe(wiring.Component):
    """The delay core with its settings shifted in from ``uart_rx`` (see the module)."""

    uart_rx:   In(1)
    button:    In(1)
    laser:     Out(1)
    tdc_start: Out(1)

    def __init__(self, clock_hz):
        self.clock_hz = clock_hz
        super().__init__()
        # The baseline stays the LFSR delay core alone: no keyed source (its key would
        # need another chain; up5k_fit.py measures it inside the top level instead).

    def elaborate(self, platform):
        m = Module()

        m.submodules.core = core = DelayCore(clock_hz=self.clock_hz, keyed=False)
        bit = Signal()
        enable = Signal()
        m.submodules.bit_sync = FFSynchronizer(self.uart_rx, bit)
        m.submodules.enable_sync = FFSynchronizer(self.button, enable)
        chain = Signal(len(core.settings.as_value()) + 1)
        m.d.sync += chain.eq(Cat(bit, chain))
        m.d.comb += [
            core.settings.eq(chain),
            core.update.eq(chain[-1]),
            core.enable.eq(enable),
            self.laser.eq(core.laser),
            self.tdc_start.eq(core.tdc_start),
        ]

        return m
