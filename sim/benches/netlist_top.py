"""cocotb tests of a board's top level that only a board build has: power-up (the PLL's lock
and the board's reset hold, :class:`fliss.boards.PllClocking`) and the delay sequences of every
mode the build has, through the pins.

The top level is the wrapper of :mod:`fliss.boards.netlist` around a board's netlist: ``rst``
high holds the PLL unlocked, and its clock runs at the board's design clock. The settings come
from :mod:`fliss.sim.benches.top` (``FLISS_TB_*``); ``FLISS_TB_KEYED`` says whether the build has
the keyed delay source.
"""

import os

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.simtime import get_sim_time
from cocotb.triggers import ClockCycles, FallingEdge, ReadOnly, RisingEdge, Timer

from ... import protocol
from ...hdl.delay.modes import DelayMode
from ...hdl.protocol import PacketType, registers_layout
from ...hdl.registers import BY_NAME, words_of
from ..models.scheduler import Settings, simulate
from .uart_bfm import UartSink, UartSource
from .top import CLOCK_PERIOD_PS, INIT_CYCLES, MAXIMA, TopTB, write_payload


KEYED = os.environ.get("FLISS_TB_KEYED", "1") == "1"
#: Power-up test up to the first PING only (Icarus, whose gate-level runs are slow).
SHORT = os.environ.get("FLISS_TB_SHORT") == "1"
#: Pulses compared per delay mode.
PULSES = int(os.environ.get("FLISS_TB_PULSES", 300))
OUTPUTS = ("uart_tx", "laser", "tdc_start", "aggressor_laser", "running")
#: Output levels from power-up until the first command: idle line, no laser, not running.
IDLE = {"uart_tx": 1, "laser": 0, "tdc_start": 0, "aggressor_laser": 0, "running": 0}


def _levels(dut):
    return {name: str(getattr(dut, name).value) for name in OUTPUTS}


@cocotb.test()
async def test_power_up(dut):
    """From configuration on, before the PLL locks and through the reset hold, every output is
    at its idle level (never X, the line never leaves idle, no laser pulse); then the board
    answers PING, IDENTIFY and GET_STATUS as the model does, all counters zero, and sends
    nothing else. Must run first: the simulation's start is the board's configuration."""
    dut.rst.value = 1
    for name in ("sensor_valid", "sensor_timestamp", "sensor_address", "sensor_collision",
                 "photon_hit"):
        getattr(dut, name).value = 0
    dut.uart_rx.value = 1
    Clock(dut.clk, CLOCK_PERIOD_PS, unit="ps").start()
    want = {name: str(level) for name, level in IDLE.items()}
    # Unlocked for a while, then locked: the design leaves reset INIT_CYCLES after the lock.
    for cycle in range(200 + INIT_CYCLES + 200):
        await RisingEdge(dut.clk)
        if cycle == 200:
            dut.rst.value = 0
        await ReadOnly()
        assert _levels(dut) == want, (cycle, _levels(dut))
    await Timer(1, unit="ps")
    tb = TopTB(dut)
    tb.source = UartSource(dut.uart_rx, tb.model.baud)
    tb.sink = UartSink(dut.uart_tx, tb.model.baud)
    await ClockCycles(dut.clk, 10)
    assert not tb.sink.received, bytes(tb.sink.received)
    assert (await tb.command(PacketType.PING)).type == PacketType.ACK
    if SHORT:
        return
    await tb.command(PacketType.IDENTIFY)
    status = await tb.status()
    assert set(status.values()) == {0} or {k for k, v in status.items() if v} == {"commands"}, \
        status
    assert not tb.data_packets and not tb.link_reports


def _settings(mode, period):
    # Settings of each delay mode, for a few hundred pulses in a short run.
    return Settings(mode=mode, length=5, mask_width=5, seed=11, period=period, pulse_width=3,
                    key=0x0123456789ABCDEF0123, iv=0x5A5A5A5A5A5A5A5A5A5A)


async def _edges(dut, pin, times):
    # Cycle numbers of the rising edges of `pin`, and high times, appended to `times`.
    while True:
        await RisingEdge(pin)
        rise = round(get_sim_time("ps") / CLOCK_PERIOD_PS)
        await FallingEdge(pin)
        times.append((rise, round(get_sim_time("ps") / CLOCK_PERIOD_PS) - rise))


@cocotb.test()
async def test_delay_modes(dut):
    """Each delay mode the build has: the laser's rising edges of a run, PULSES of them, are
    the model's fire cycles (:func:`fliss.sim.models.scheduler.simulate`) up to one offset,
    every pulse as wide as set, and the TDC start rises with each."""
    tb = TopTB(dut)
    await tb.start()
    modes = [DelayMode.OFF, DelayMode.MSEQ, DelayMode.MASKED] + ([DelayMode.KEYED] if KEYED
                                                                 else [])
    period = max(BY_NAME["period"].minimum, 64)
    for mode in modes:
        settings = _settings(mode, period)
        if mode == DelayMode.KEYED:
            values = {**words_of(settings.iv, "iv"), **words_of(settings.key, "key")}
            names = ["iv0", "iv1", "iv2", "key0", "key1", "key2"]
            reply = await tb.command(PacketType.WRITE, protocol.pack(
                registers_layout(len(names)), address=BY_NAME["iv0"].address,
                values=[values[name] for name in names]))
            assert reply.type == PacketType.ACK, reply
        await tb.write(delay_mode=mode.value, length=settings.length,
                       mask_width=min(settings.mask_width, MAXIMA.get("mask_width", 32)),
                       seed=settings.seed, period=settings.period,
                       pulse_width=settings.pulse_width)
        lasers, starts = [], []
        monitors = [cocotb.start_soon(_edges(dut, dut.laser, lasers)),
                    cocotb.start_soon(_edges(dut, dut.tdc_start, starts))]
        await tb.command(PacketType.START)
        expected = simulate(settings, (PULSES + 2) * (period + 40))
        await ClockCycles(dut.clk, expected[PULSES][0] + 200)
        await tb.command(PacketType.STOP)
        for monitor in monitors:
            monitor.cancel()
        got = np.array([rise for rise, _ in lasers[:PULSES]])
        fires = np.array([fire for fire, *_ in expected[:PULSES]])
        assert len(got) == PULSES, (mode, len(got))
        offsets = got - fires
        assert (offsets == offsets[0]).all(), (mode, np.flatnonzero(offsets != offsets[0])[:8])
        assert [width for _, width in lasers[:PULSES]] == [settings.pulse_width] * PULSES
        assert [rise for rise, _ in starts[:PULSES]] == list(got), mode
        assert len({delay for _, delay, *_ in expected[:PULSES]}) > (1 if mode.value else 0)
        dut._log.info("%s: %d pulses as the model's, offset %d cycles", mode.name, PULSES,
                      offsets[0])
    assert not [r for r in tb.link_reports if not isinstance(r, protocol.SequenceGap)]


__all__ = ["test_power_up", "test_delay_modes", "write_payload"]
