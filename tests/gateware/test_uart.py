"""UART transmitter and receiver against the bit-level model (fliss.sim.models.uart)."""

import pytest
from amaranth.hdl import Elaboratable, Module, Signal

from fliss.hdl.clock import DEFAULT_CLOCK_HZ, FRACTION_BITS, MIN_BIT_CYCLES, bit_cycles
from fliss.hdl.link.uart import UartTx, UartRx, CHARACTER_BITS
from fliss.sim.models import uart as model
from fliss.sim.models import lfsr
from simulation import simulate


CLOCK = DEFAULT_CLOCK_HZ
BAUDS = [115_200, 1_000_000, 2_000_000, 3_000_000, 12_000_000]


def prbs(count, seed=1):
    """PRBS bytes: 9-bit m-sequence states of the project's LFSR model, low byte."""
    return bytes(int(s) & 0xff for s in lfsr.states(9, seed, count, steps=8))


def byte_count(baud, cycles=4000):
    # Enough characters to cover about `cycles` clock cycles, at least 3.
    return max(3, cycles * baud // (CLOCK * CHARACTER_BITS))


def run(dut, *testbenches, background=(), cycle=None):
    m = Module()
    m.submodules.dut = dut
    if cycle is not None:
        m.d.sync += cycle.eq(cycle + 1)
    simulate(m, *testbenches, background=background, clock_hz=CLOCK)


# Parameters

@pytest.mark.parametrize("baud", BAUDS)
def test_baud_within_tolerance(baud):
    actual = CLOCK * (1 << FRACTION_BITS) / bit_cycles(CLOCK, baud)
    assert abs(actual / baud - 1) < 0.001


def test_baud_too_fast(construction_error):
    assert construction_error(lambda: UartTx(clock_hz=CLOCK, baud=21_000_000)) == (
        "Baud rate 21000000 cannot be met within 2% from a 80000000 Hz clock: the closest is "
        "20000000 baud (-4.8%), as a bit lasts at least 4 cycles")
    assert construction_error(lambda: UartRx(clock_hz=CLOCK, baud=21_000_000)).startswith(
        "Baud rate 21000000 cannot be met within 2%")
    # 20.2 Mbaud runs at 20 Mbaud, 1 % off: accepted.
    assert bit_cycles(CLOCK, 20_200_000) == MIN_BIT_CYCLES << FRACTION_BITS


@pytest.mark.parametrize("clock_hz, baud, message", [
    (0, 115_200, "Clock frequency must be positive, not 0"),
    (CLOCK, -1, "Baud rate must be positive, not -1"),
    (CLOCK, "fast", "Baud rate must be positive, not 'fast'"),
])
def test_bad_parameters(construction_error, clock_hz, baud, message):
    assert construction_error(lambda: UartRx(clock_hz=clock_hz, baud=baud)) == message


# Transmitter

@pytest.mark.parametrize("baud", BAUDS)
def test_tx_matches_model(baud):
    data = prbs(byte_count(baud), seed=baud)
    dut = UartTx(clock_hz=CLOCK, baud=baud)
    expected = model.tx_runs(data, CLOCK, baud)
    total = sum(count for _, count in expected)
    changes = []
    cycle = Signal(32)

    async def send(ctx):
        for byte in data:
            ctx.set(dut.i.valid, 1)
            ctx.set(dut.i.payload, byte)
            await ctx.tick().until(dut.i.ready)
        ctx.set(dut.i.valid, 0)
        await ctx.tick().repeat(total - ctx.get(cycle) + 10)

    async def monitor(ctx):
        while True:
            value, = await ctx.changed(dut.tx)
            changes.append((ctx.get(cycle), value))

    run(dut, send, background=[monitor], cycle=cycle)
    # Rebuild runs from the changes; the line is idle (1) from cycle 0.
    runs, level, start = [], 1, 0
    for at, value in changes:
        runs.append((level, at - start))
        level, start = value, at
    runs.append((level, None))
    assert runs[:-1] == expected[:-1]
    assert runs[-1][0] == 1 and expected[-1][0] == 1
    assert len(changes) > 2 * len(data)


# Receiver

def drive_and_collect(dut, runs):
    received = []

    async def drive(ctx):
        for level, count in runs:
            ctx.set(dut.rx, level)
            await ctx.tick().repeat(count)
        await ctx.tick().repeat(4)

    async def collect(ctx):
        ctx.set(dut.o.ready, 1)
        while True:
            await ctx.posedge(dut.o.valid)
            received.append(ctx.get(dut.o.payload))

    run(dut, drive, background=[collect])
    return received


@pytest.mark.parametrize("baud", BAUDS + [20_000_000])
@pytest.mark.parametrize("mismatch", [-0.02, 0.0, +0.02])
def test_rx_matches_model(baud, mismatch):
    data = prbs(byte_count(baud), seed=baud + 7)
    runs = model.line_runs(data, CLOCK, baud * (1 + mismatch), lead_bits=0.37)
    dut = UartRx(clock_hz=CLOCK, baud=baud)
    received = drive_and_collect(dut, runs)
    expected, errors = model.receive(model.expand(runs), CLOCK, baud)
    assert received == [byte for _, byte in expected]
    assert errors == []
    assert bytes(received) == data


@pytest.mark.parametrize("mismatch", [-0.04, +0.035])
@pytest.mark.parametrize("lead_bits", [0.0, 0.5])
def test_rx_tolerance_12m(mismatch, lead_bits):
    baud = 12_000_000
    data = prbs(60, seed=5)
    runs = model.line_runs(data, CLOCK, baud * (1 + mismatch), lead_bits=lead_bits)
    dut = UartRx(clock_hz=CLOCK, baud=baud)
    received = drive_and_collect(dut, runs)
    expected, errors = model.receive(model.expand(runs), CLOCK, baud)
    assert received == [byte for _, byte in expected]
    assert bytes(received) == data and errors == []


@pytest.mark.parametrize("baud", [1_000_000, 12_000_000])
def test_rx_framing_errors(baud):
    data = prbs(24, seed=3)
    bad = {0, 5, 6, 17, 23}
    runs = model.line_runs(data, CLOCK, baud, gap_bits=2, bad_stop=bad)
    dut = UartRx(clock_hz=CLOCK, baud=baud)
    received = []
    strobes = []

    async def drive(ctx):
        for level, count in runs:
            ctx.set(dut.rx, level)
            await ctx.tick().repeat(count)
        await ctx.tick().repeat(4)
        assert ctx.get(dut.framing_errors) == len(bad)

    async def collect(ctx):
        ctx.set(dut.o.ready, 1)
        while True:
            await ctx.posedge(dut.o.valid)
            received.append(ctx.get(dut.o.payload))

    async def errors(ctx):
        while True:
            await ctx.posedge(dut.framing_error)
            strobes.append(1)

    run(dut, drive, background=[collect, errors])
    expected, expected_errors = model.receive(model.expand(runs), CLOCK, baud)
    assert received == [byte for _, byte in expected]
    assert len(strobes) == len(expected_errors) == len(bad)
    assert bytes(received) == bytes(b for i, b in enumerate(data) if i not in bad)


def test_rx_break_counts_once_and_glitch_is_ignored():
    baud = 12_000_000
    runs = [(1, 50), (0, 1), (1, 50),           # one-cycle glitch: not a start bit
            (0, 400), (1, 50)]                  # break: one framing error
    runs += model.line_runs(b"\x5a", CLOCK, baud)
    dut = UartRx(clock_hz=CLOCK, baud=baud)
    received = drive_and_collect(dut, runs)
    expected, errors = model.receive(model.expand(runs), CLOCK, baud)
    assert received == [byte for _, byte in expected] == [0x5a]
    assert len(errors) == 1


def test_rx_overrun_counted():
    baud = 12_000_000
    data = b"\x11\x22\x33"
    runs = model.line_runs(data, CLOCK, baud)

    dut = UartRx(clock_hz=CLOCK, baud=baud)

    async def drive(ctx):
        for level, count in runs:
            ctx.set(dut.rx, level)
            await ctx.tick().repeat(count)
        await ctx.tick().repeat(4)
        assert ctx.get(dut.overruns) == 2
        assert ctx.get(dut.o.valid) == 1
        assert ctx.get(dut.o.payload) == 0x11
        assert ctx.get(dut.framing_errors) == 0

    run(dut, drive)


# Loopback

class _Loopback(Elaboratable):
    def __init__(self, baud):
        self.tx = UartTx(clock_hz=CLOCK, baud=baud)
        self.rx = UartRx(clock_hz=CLOCK, baud=baud)

    def elaborate(self, platform):
        m = Module()
        m.submodules.tx = self.tx
        m.submodules.rx = self.rx
        m.d.comb += self.rx.rx.eq(self.tx.tx)
        return m


@pytest.mark.parametrize("baud", [115_200, 3_000_000, 12_000_000, 20_000_000])
def test_loopback(baud):
    data = prbs(byte_count(baud, 12000), seed=11)
    dut = _Loopback(baud)
    received = []

    async def send(ctx):
        for byte in data:
            ctx.set(dut.tx.i.valid, 1)
            ctx.set(dut.tx.i.payload, byte)
            await ctx.tick().until(dut.tx.i.ready)
        ctx.set(dut.tx.i.valid, 0)
        await ctx.tick().until(~dut.tx.busy)
        await ctx.tick().repeat(2 * CLOCK // baud + 4)
        assert ctx.get(dut.rx.framing_errors) == 0
        assert ctx.get(dut.rx.overruns) == 0

    async def collect(ctx):
        ctx.set(dut.rx.o.ready, 1)
        while True:
            await ctx.posedge(dut.rx.o.valid)
            received.append(ctx.get(dut.rx.o.payload))

    run(dut, send, background=[collect])
    assert bytes(received) == data
