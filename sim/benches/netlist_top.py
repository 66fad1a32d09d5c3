"""cocotb tests of a board's top level that a board build's netlist runs, through the pins:
power-up (the PLL's lock and the board's reset hold, :class:`fliss.boards.PllClocking`), the
link (a register of every group written and read back, a refusal and a NAK), the delay
sequences of every mode the build has, and a histogram of injected events in compact readout.
Each is short enough for a gate-level run in CI; the longer benches of
:mod:`fliss.sim.benches.top` add the rest.

The top level is the wrapper of :mod:`fliss.boards.netlist` around a board's netlist: ``rst``
high holds the PLL unlocked, and its clock runs at the board's design clock. The settings come
from :mod:`fliss.sim.benches.top` (``FLISS_TB_*``); ``FLISS_TB_KEYED`` says whether the build has
the keyed delay source.
"""

import os
import random

import cocotb
import numpy as np
from cocotb.clock import Clock
from cocotb.simtime import get_sim_time
from cocotb.triggers import ClockCycles, FallingEdge, ReadOnly, RisingEdge, Timer

from ... import protocol
from ...hdl.delay.modes import DelayMode
from ...hdl.protocol import LINK_COUNTERS, Nak, PacketType, registers_layout
from ...hdl.registers import BY_NAME, GROUPS, REGISTERS, words_of
from ...protocol.packets import HISTOGRAM_TYPES
from ..models.scheduler import Settings, simulate
from .uart_bfm import UartSink, UartSource
from .top import (CLOCK_PERIOD_PS, INIT_CYCLES, MAXIMA, TopTB, histogram_frame, inject_events,
                  read_payload, write_payload)


KEYED = os.environ.get("FLISS_TB_KEYED", "1") == "1"
#: Whether the build sends compact histogram chunks where shorter (else full ones only).
COMPACT = os.environ.get("FLISS_TB_COMPACT", "1") == "1"
#: How far the power-up test goes on a slow gate-level run (Icarus): ``1``, to the first PING;
#: ``levels``, the outputs' levels through the reset hold only.
SHORT = os.environ.get("FLISS_TB_SHORT", "")
#: Cycles with the PLL unlocked before, and locked after, the reset hold of the power-up test.
UNLOCKED_CYCLES = int(os.environ.get("FLISS_TB_UNLOCKED_CYCLES", 200))
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
    # cocotb's clock in Python, not in the GPI: the GPI's first edge comes at time 0, ahead of
    # the reset written above, and the netlist's registers would take X from it
    Clock(dut.clk, CLOCK_PERIOD_PS, unit="ps", impl="py").start()
    want = {name: str(level) for name, level in IDLE.items()}
    # Unlocked for a while, then locked: the design leaves reset INIT_CYCLES after the lock.
    for cycle in range(UNLOCKED_CYCLES + INIT_CYCLES + 200):
        await RisingEdge(dut.clk)
        if cycle == UNLOCKED_CYCLES:
            dut.rst.value = 0
        await ReadOnly()
        assert _levels(dut) == want, (cycle, _levels(dut))
    if SHORT == "levels":
        return
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


async def _write_many(tb, **values):
    # One WRITE of registers at consecutive addresses, in address order; checked by the model.
    names = sorted(values, key=lambda name: BY_NAME[name].address)
    first = BY_NAME[names[0]].address
    assert [BY_NAME[name].address for name in names] == list(range(first, first + len(names)))
    reply = await tb.command(PacketType.WRITE, protocol.pack(
        registers_layout(len(names)), address=first, values=[values[name] for name in names]))
    assert reply.type == PacketType.ACK, (values, reply)


#: One register of each group and a value for it other than its reset value (capped at a
#: smaller build's maximum), which the settings' checks accept with the others at reset.
LINK_WRITES = {"pulse_width": 9, "aggressor_offset": 3, "aggressor_period": 40, "tdc_source": 1,
               "gate_end": 5000, "integration": 123_456, "depth_threshold": 9, "fine_lsb": 2,
               "key1": 0x89ABCDEF}


@cocotb.test()
async def test_link(dut):
    """The link and the register file: a register of every group written and all read back
    (the values written, 0 for the key's, and the command model's reply); a value above a
    register's maximum refused; a frame with a damaged CRC answered by a NAK of its reason and
    counted."""
    tb = TopTB(dut)
    await tb.start()
    writes = {name: min(value, MAXIMA.get(name, value)) for name, value in LINK_WRITES.items()}
    assert {BY_NAME[name].group for name in writes} == {group.name for group in GROUPS}
    for name, value in writes.items():
        reply = await tb.command(PacketType.WRITE, write_payload(BY_NAME[name].address, value))
        assert reply.type == PacketType.ACK, (name, value, reply)
    reply = await tb.command(PacketType.READ, read_payload(0, len(REGISTERS)))
    values = protocol.unpack(registers_layout(len(REGISTERS)), reply.payload)["values"]
    # (a write-only register, the key's, reads as 0)
    assert {name: values[BY_NAME[name].address] for name in writes} == {
        name: 0 if BY_NAME[name].write_only else value for name, value in writes.items()}
    # A refusal: the model's NAK, nothing applied.
    register = BY_NAME["delay_mode"]
    reply = await tb.command(PacketType.WRITE, write_payload(register.address,
                                                             register.maximum + 1))
    assert reply.type == PacketType.NAK, reply
    # A damaged frame: the CRC's last byte flipped (never to the delimiter).
    frame = bytearray(protocol.encode_frame(PacketType.PING, tb.encoder.seq))
    frame[-2] = frame[-2] ^ 0x01 or 0x02
    check = protocol.FrameDecoder(synced=True).feed(bytes(frame))
    assert len(check) == 1 and isinstance(check[0], protocol.LinkError), check
    await tb.source.send(bytes(frame))
    reply = await tb.next_packet(types={PacketType.NAK})
    assert reply.payload == protocol.pack(Nak, code=check[0].code), (check, reply)
    status = await tb.status()
    assert {name: status[name] for name in LINK_COUNTERS.values()} == {
        name: int(code == check[0].code) for code, name in LINK_COUNTERS.items()}, status
    reply = await tb.command(PacketType.PING)
    assert reply.type == PacketType.ACK, reply
    assert not [r for r in tb.link_reports if not isinstance(r, protocol.SequenceGap)]


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
    # (one bin per frame: the histogram that STOP ends is read out in one short chunk)
    await tb.write(bin_shift=13)
    for mode in modes:
        settings = _settings(mode, period)
        if mode == DelayMode.KEYED:
            values = {**words_of(settings.iv, "iv"), **words_of(settings.key, "key")}
            names = ["iv0", "iv1", "iv2", "key0", "key1", "key2"]
            reply = await tb.command(PacketType.WRITE, protocol.pack(
                registers_layout(len(names)), address=BY_NAME["iv0"].address,
                values=[values[name] for name in names]))
            assert reply.type == PacketType.ACK, reply
        # The victim's settings in one WRITE (addresses delay_mode ... pulse_width).
        await _write_many(tb, delay_mode=mode.value, length=settings.length,
                          mask_width=min(settings.mask_width, MAXIMA.get("mask_width", 32)),
                          seed=settings.seed, period=settings.period, grid=0,
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


@cocotb.test()
async def test_histogram_compact(dut):
    """A histogram of events injected on the sensor bus, each bin the bincount of the events of
    the frame's pixels, the others and the collisions dropped: two pixels of 256 bins read out
    in compact chunks (the board's choice for a sparse frame), or, on a build without them,
    one pixel of 64 bins in full chunks."""
    tb = TopTB(dut)
    await tb.start()
    tb.data_packets = []
    pixel_bits = min(1, MAXIMA.get("pixel_bits", 6))
    first_pixel, shift = 3, (5 if COMPACT else 7)
    await _write_many(tb, bin_shift=shift, integration=10_000_000, collisions=1,
                      pixel_bits=pixel_bits, first_pixel=first_pixel, full_readout=0)
    await tb.command(PacketType.START)
    timestamps, addresses, collisions = await inject_events(
        tb, random.Random(23), 200, pixel_bits=pixel_bits, first_pixel=first_pixel)
    await ClockCycles(dut.clk, 50)
    await tb.command(PacketType.STOP)
    bins = 1 << (13 - shift)
    counts = await histogram_frame(tb, 0, bins << pixel_bits, split=(pixel_bits, first_pixel))
    pixel = addresses - first_pixel
    inside = (collisions == 0) & (pixel >= 0) & (pixel < (1 << pixel_bits))
    want = np.bincount(pixel[inside] * bins + (timestamps[inside] >> shift),
                       minlength=bins << pixel_bits)
    assert inside.sum() > 80
    assert np.array_equal(counts, want), np.flatnonzero(counts != want)[:8]
    types = {p.type for p in tb.data_packets + tb.packets if p.type in HISTOGRAM_TYPES}
    assert types == {PacketType.HISTOGRAM_COMPACT if COMPACT else PacketType.HISTOGRAM}, types


__all__ = ["test_power_up", "test_link", "test_delay_modes", "test_histogram_compact",
           "write_payload"]
