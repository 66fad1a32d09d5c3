"""The fine TDC on the virtual board: a top level whose delay line's first stage is a port, and
the cocotb driver that fills it from the modelled line.

In a simulation the fine TDC's delay line has no carry chain: its first flip-flop stage is the
port :class:`~fliss.hdl.finetdc.line.DelayLine` ``sampled``. :class:`FineTdcTop` is the top
level with the fine TDC whose ``fine_sampled`` port drives it, and whose ``fine_input`` port
shows the register ``tdc_input`` (a simulation build only: the board has neither).
:class:`FineLoopback` drives ``fine_sampled`` with :meth:`fliss.sim.models.finetdc.Line.samples`:

* ``tdc_input`` 1, the on-chip oscillator: hits at a random phase, ``oscillator_hz`` on
  average, each high for two clock cycles (shorter than the real one's some 200 ns, which the
  line would show no differently: the encoder counts a hit when a sample follows an all-zero
  one);
* ``tdc_input`` 0, the photon pin: with ``jumper`` (``"laser"`` or ``"aggressor"``), a jumper
  wire from that trigger output, ``jumper_delay_s`` after its clock edge; else nothing (the pin
  gets no photons on the virtual board). The same jumper drives the coarse TDC's pin
  (:class:`~fliss.sim.boards.jumper.Jumper`).
* ``tdc_input`` 2 and 3, the internal loopback: the laser's or the aggressor's output read back
  at its pad, ``pad_delay_s`` after its clock edge (the model board's,
  :data:`~fliss.sim.boards.loopback.PAD_DELAY_S`).

Both loopbacks have a Gaussian jitter of ``jitter_s``.

The samples of a hit go to the port from the clock edge after it until the line has emptied.
"""

import numpy as np
from cocotb.triggers import ClockCycles, First, RisingEdge

from ...hdl.finetdc import TAPS, HitInput
from ...hdl.top import FlissTop
from ..models.finetdc import Line
from .loopback import JITTER_S, JUMPER_DELAY_S, PAD_DELAY_S
from amaranth.lib.wiring import In, Out


__all__ = ["FineTdcTop", "FineLoopback"]


class FineTdcTop(FlissTop):
    """:class:`~fliss.hdl.top.FlissTop` with the fine TDC, its delay line's first stage from
    the port ``fine_sampled`` (``In(TAPS)``), ``tdc_input`` on ``fine_input`` (``Out(2)``): for
    simulations only."""

    def __init__(self, **options):
        super().__init__(fine_tdc=True, **options)

    def _ports(self):
        return {**super()._ports(), "fine_sampled": In(TAPS), "fine_input": Out(HitInput)}

    def _fine_tdc(self, m, registers, core, link, captures):
        selected = super()._fine_tdc(m, registers, core, link, captures)
        fine = m.submodules.fine
        m.d.comb += [fine.sampled.eq(self.fine_sampled),
                     self.fine_input.eq(registers.fine_tdc.input)]
        return selected


class FineLoopback:
    """Drives ``dut.fine_sampled`` of a :class:`FineTdcTop` (see the module's description)."""

    def __init__(self, dut, clock_hz, *, line=None, oscillator_hz=2.4e6, jumper=None,
                 jumper_delay_s=JUMPER_DELAY_S, pad_delay_s=PAD_DELAY_S, jitter_s=JITTER_S,
                 seed=None):
        self.dut = dut
        self.cycle_s = 1 / clock_hz
        self.line = Line() if line is None else line
        self.oscillator_hz = oscillator_hz
        self.rng = np.random.default_rng(seed)
        self.hits = 0
        triggers = {None: None, "laser": dut.laser, "aggressor": dut.aggressor_laser}
        # tdc_input -> (the trigger output that drives the line, its delay)
        self.loops = {HitInput.LASER.value: (dut.laser, pad_delay_s),
                      HitInput.AGGRESSOR.value: (dut.aggressor_laser, pad_delay_s)}
        if jumper is not None:
            self.loops[HitInput.PIN.value] = (triggers[jumper], jumper_delay_s)
        self.jitter_s = jitter_s
        dut.fine_sampled.value = 0

    def start(self):
        from cocotb import start_soon
        start_soon(self._run())

    def _word(self, bits):
        # Tap 0 is the least significant bit
        return int.from_bytes(np.packbits(bits, bitorder="little").tobytes(), "little")

    async def _drive(self, tau_s, width_s):
        # The samples at this and the following clock edges, until the line is empty
        dut = self.dut
        while True:
            bits = self.line.samples([tau_s], self.rng, width_s=width_s)[0]
            dut.fine_sampled.value = self._word(bits)
            if not bits.any() and tau_s >= width_s:     # (fallen, and past the line)
                return
            await RisingEdge(dut.clk)
            tau_s += self.cycle_s

    async def _run(self):
        dut = self.dut
        while True:
            source = int(dut.fine_input.value)
            if source in self.loops:
                trigger, delay_s = self.loops[source]
                edge = RisingEdge(trigger)
                if await First(edge, ClockCycles(dut.clk, 64)) is not edge:
                    continue
                await RisingEdge(dut.clk)
                self.hits += 1
                delay_s += self.rng.normal(0, self.jitter_s)
                await self._drive(self.cycle_s - delay_s, 1 * self.cycle_s)
            elif source == HitInput.OSCILLATOR.value:
                gap = self.rng.exponential(1 / (self.oscillator_hz * self.cycle_s))
                await ClockCycles(dut.clk, max(1, int(gap)))
                self.hits += 1
                await self._drive(self.rng.uniform(0, self.cycle_s), 2 * self.cycle_s)
            else:
                await ClockCycles(dut.clk, 64)
