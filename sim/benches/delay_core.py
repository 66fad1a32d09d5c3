"""cocotb testbench of :class:`fliss.hdl.delay.core.DelayCore` (generated Verilog).

A :class:`DelayCoreTB` owns the clock, reset, the settings driver, a monitor of the laser and
TDC start pins, and the reference model (:func:`fliss.sim.models.scheduler.simulate`). Tests compare
every pulse bit for bit: the cycle of each laser rising edge and TDC start, the delay, the pulse
index and the laser pulse width.
"""

import os
import random

import cocotb
from cocotb.clock import Clock
from cocotb.simtime import get_sim_time
from cocotb.triggers import ClockCycles, FallingEdge, ReadOnly, RisingEdge

from ...hdl.clock import DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ, period_cycles
from ...hdl.delay.modes import DelayMode
from ...hdl.delay.keyed import Keying
from ...hdl.registers import DelaySettings, words_of
from ..models.delay import KeyedRestarts
from ..models.scheduler import LATENCY, Settings, simulate


CLOCK_PERIOD_PS = round(1e12 / DEFAULT_CLOCK_HZ)
PERIOD = period_cycles(DEFAULT_CLOCK_HZ, DEFAULT_PRF_HZ)
RUN_CYCLES = 100_000

#: Pulses of the keyed test (at least 100 000 by default).
KEYED_PULSES = int(os.environ.get("FLISS_TB_KEYED_PULSES", "100000"))

#: Paper, Table 2: effective PRF at 80 MHz and 1 MHz nominal, in Hz, to the digits printed there.
TABLE_2 = {3: 963.9e3, 4: 919.5e3, 5: 842.1e3, 6: 720.7e3, 8: 386.5e3}


class DelayCoreTB:
    def __init__(self, dut):
        self.dut = dut
        self.starts = []      # edge numbers of tdc_start
        self.rises = []       # edge numbers of laser rising edges
        self.widths = []      # laser high time in cycles
        self.fires = []       # (edge of fire, fire_delay, pulse_index)
        self._monitors = []

    def cycle(self):
        """Number of the latest rising clock edge."""
        return round(get_sim_time("ps") / CLOCK_PERIOD_PS)

    async def start(self):
        Clock(self.dut.clk, CLOCK_PERIOD_PS, unit="ps", impl="gpi").start()
        self.dut.rst.value = 1
        self.dut.enable.value = 0
        self.dut.update.value = 0
        self.dut.rekey.value = 0
        await ClockCycles(self.dut.clk, 2)
        self.dut.rst.value = 0
        for monitor in (self._monitor_fire, self._monitor_start, self._monitor_laser):
            self._monitors.append(cocotb.start_soon(monitor()))

    def stop_monitors(self):
        for task in self._monitors:
            task.cancel()

    def drive(self, settings):
        # (one vector: the port is a DelaySettings struct)
        self.dut.settings.value = DelaySettings().const(
            {name: getattr(settings, name) for name, _ in DelaySettings()}).as_value().value

    def drive_keying(self, key, iv):
        self.dut.keying.value = Keying.const(
            {**words_of(key, "key"), **words_of(iv, "iv")}).as_value().value

    async def edge(self):
        """Wait for the next rising clock edge; return its number."""
        await RisingEdge(self.dut.clk)
        return self.cycle()

    async def _monitor_fire(self):
        while True:
            await RisingEdge(self.dut.fire)
            await ReadOnly()
            if not self.dut.fire.value:
                # (a glitch: `fire` is combinational from `update`, which this testbench
                # writes in the same time step as the clock edge)
                continue
            self.fires.append((self.cycle(), int(self.dut.fire_delay.value),
                               int(self.dut.pulse_index.value)))

    async def _monitor_start(self):
        while True:
            await RisingEdge(self.dut.tdc_start)
            self.starts.append(self.cycle())

    async def _monitor_laser(self):
        while True:
            await RisingEdge(self.dut.laser)
            rise = self.cycle()
            self.rises.append(rise)
            await FallingEdge(self.dut.laser)
            self.widths.append(self.cycle() - rise)

    def check(self, expected, *, period=None, min_pulses=2):
        """Compare the recorded pulses with the model's ``(fire, delay, width, index)`` list.

        Also checks that the laser goes low between pulses and, given ``period`` (interval
        mode), that no interval between laser edges is shorter than it.
        """
        mismatches = 0
        got_fires = self.fires[:len(expected)]
        if len(self.fires) != len(expected):
            self.dut._log.error("pulse count: RTL %d, model %d", len(self.fires), len(expected))
            mismatches += 1
        for (fire, delay, _width, index), got, start, rise in zip(
                expected, got_fires, self.starts, self.rises):
            if got != (fire, delay, index) or start != fire + LATENCY or rise != fire + LATENCY:
                if mismatches < 10:
                    self.dut._log.error("pulse %d: model fire %d delay %d, RTL %r, tdc_start %d, "
                                        "laser %d", index, fire, delay, got, start, rise)
                mismatches += 1
        for index, width in enumerate(self.widths[:len(expected)]):
            if width != expected[index][2]:
                mismatches += 1
        merged = [(a, w, b) for a, w, b in zip(self.rises, self.widths, self.rises[1:])
                  if b <= a + w]
        assert not merged, f"laser did not go low between pulses: {merged[:5]}"
        if period is not None:
            short = [b - a for a, b in zip(self.rises, self.rises[1:]) if b - a < period]
            assert not short, f"intervals shorter than T = {period}: {short[:5]}"
        assert mismatches == 0, f"{mismatches} mismatches against the model"
        assert len(expected) >= min_pulses, f"only {len(expected)} pulses compared"
        return len(expected)


async def run_and_check(dut, settings, cycles=RUN_CYCLES, min_pulses=2):
    tb = DelayCoreTB(dut)
    await tb.start()
    tb.drive(settings)
    enable = await tb.edge()
    dut.enable.value = 1
    await ClockCycles(dut.clk, cycles)
    last = tb.cycle()
    tb.stop_monitors()
    expected = simulate(settings, last, enable=enable)
    # Pulses whose laser edge would fall after the last edge seen are not compared.
    expected = [p for p in expected if p[0] + LATENCY <= last]
    tb.fires = tb.fires[:len(expected)]
    compared = tb.check(expected, period=None if settings.grid else settings.period,
                        min_pulses=min_pulses)
    dut._log.info("%d pulses compared over %d cycles", compared, cycles)
    return tb


@cocotb.test()
@cocotb.parametrize(length=[3, 4, 5, 6, 8, 16, 32])
async def test_mseq(dut, length):
    """m-sequence delays and fire times against the model, 100 000 cycles.

    With L = 16 and 32 the delays reach 2**L - 2 cycles, so only a few pulses fit in the run:
    their delays are checked in bulk by ``tb_delay_source``.
    """
    settings = Settings(mode=DelayMode.MSEQ, length=length, seed=random.randrange(1, 1 << length),
                        period=PERIOD, pulse_width=3).check()
    await run_and_check(dut, settings, min_pulses=100 if length <= 8 else 0)


@cocotb.test()
@cocotb.parametrize(mask_width=[1, 2, 3, 4, 5, 6])
async def test_masked(dut, mask_width):
    """Masked 32-bit LFSR delays and fire times against the model, 100 000 cycles."""
    settings = Settings(mode=DelayMode.MASKED, mask_width=mask_width,
                        seed=random.randrange(1, 1 << 32), period=PERIOD, pulse_width=2).check()
    await run_and_check(dut, settings)


@cocotb.test()
@cocotb.parametrize(mode=[DelayMode.OFF, DelayMode.MSEQ, DelayMode.MASKED])
async def test_grid(dut, mode):
    """Grid mode: pulse k at k T + R[k], so the effective PRF is the nominal PRF."""
    settings = Settings(mode=mode, length=6, mask_width=6, seed=random.randrange(1, 64),
                        period=PERIOD, grid=True, pulse_width=4).check()
    tb = await run_and_check(dut, settings, cycles=20_000, min_pulses=200)
    # t[N] - t[0] = N T + R[N] - R[0]: within one delay range of N T.
    pulses = len(tb.rises) - 1
    span = tb.rises[-1] - tb.rises[0]
    assert abs(span - pulses * settings.period) <= 63, (span, pulses)


@cocotb.test()
@cocotb.parametrize(length=list(TABLE_2))
async def test_effective_prf(dut, length):
    """Effective PRF over whole m-sequences, measured from the laser pins, equals Table 2."""
    settings = Settings(mode=DelayMode.MSEQ, length=length, seed=1, period=PERIOD,
                        pulse_width=1).check()
    pulses = (1 << length) - 1
    tb = DelayCoreTB(dut)
    await tb.start()
    tb.drive(settings)
    await tb.edge()
    dut.enable.value = 1
    while len(tb.rises) < pulses + 1:
        await RisingEdge(dut.laser)
    await ReadOnly()
    tb.stop_monitors()
    span_cycles = tb.rises[pulses] - tb.rises[0]
    prf_hz = DEFAULT_CLOCK_HZ * pulses / span_cycles
    dut._log.info("L = %d: measured PRF_eff = %.1f Hz over %d pulses", length, prf_hz, pulses)
    assert round(prf_hz / 100) * 100 == TABLE_2[length], (prf_hz, TABLE_2[length])


@cocotb.test()
async def test_reconfigure(dut):
    """Settings changed while running apply at the next frame, restart the sequence, and never
    make a runt, merged or doubled pulse."""
    rng = random.Random(0x5EED)
    tb = DelayCoreTB(dut)
    await tb.start()
    current = Settings(mode=DelayMode.MSEQ, length=5, seed=3, period=PERIOD, pulse_width=2)
    tb.drive(current)
    enable = await tb.edge()
    dut.enable.value = 1
    updates = []
    for _ in range(40):
        await ClockCycles(dut.clk, rng.randrange(1, 400))
        mode = rng.choice([DelayMode.OFF, DelayMode.MSEQ, DelayMode.MASKED])
        length, mask_width = rng.choice([3, 4, 5, 6]), rng.randrange(1, 7)
        grid = rng.random() < 0.3
        period = rng.randrange(70, 160) if not grid else 160
        current = Settings(mode=mode, length=length, mask_width=mask_width,
                           seed=rng.randrange(1, 8), period=period, grid=grid,
                           pulse_width=rng.randrange(1, 6)).check()
        tb.drive(current)
        dut.update.value = 1
        # (high in the cycle that this edge ends: the cycle numbers the model counts, as
        # `enable` above and test_keyed's updates)
        updates.append((await tb.edge() - 1, current))
        dut.update.value = 0
    await ClockCycles(dut.clk, 500)
    last = tb.cycle()
    tb.stop_monitors()
    first = Settings(mode=DelayMode.MSEQ, length=5, seed=3, period=PERIOD, pulse_width=2)
    expected = [p for p in simulate(first, last, updates=updates, enable=enable)
                if p[0] + LATENCY <= last]
    tb.fires = tb.fires[:len(expected)]
    assert tb.check(expected, min_pulses=40) >= 40


@cocotb.test()
async def test_reset_and_restart(dut):
    """Reset or stop in the middle of a run, then start again: the sequence restarts."""
    settings = Settings(mode=DelayMode.MASKED, mask_width=5, seed=0xACE1, period=PERIOD,
                        pulse_width=3).check()
    tb = DelayCoreTB(dut)
    await tb.start()
    tb.drive(settings)
    expected = []
    for stop in ("reset", "disable", "reset"):
        enable = await tb.edge()
        dut.enable.value = 1
        await ClockCycles(dut.clk, 3_000 + 17 * len(expected))
        if stop == "reset":
            dut.rst.value = 1
        dut.enable.value = 0
        end = await tb.edge()
        expected += [p for p in simulate(settings, end, enable=enable, disable=end)]
        await ClockCycles(dut.clk, 200)  # a pulse cut by reset would fall here
        dut.rst.value = 0
        await ClockCycles(dut.clk, 5)
    tb.stop_monitors()
    assert [(d, i) for _, d, i in tb.fires] == [(d, i) for _, d, _, i in expected]
    offsets = [f - e[0] for (f, *_), e in zip(tb.fires, expected)]
    assert set(offsets) == {0}, offsets[:10]
    assert len(expected) > 100


@cocotb.test()
async def test_keyed(dut):
    """Keyed delays and fire times against the model for ``KEYED_PULSES`` pulses, over runs
    with stops and starts and updates in the middle: new keys and IVs (written, ``rekey``, in
    the cycle before the update), settings alone (the IV moves on by one), other modes and
    back. Each run's IV in use is checked on ``iv``."""
    rng = random.Random(0x7121)
    tb = DelayCoreTB(dut)
    await tb.start()
    restarts = KeyedRestarts()
    expected = []
    ivs = []
    key, iv = rng.getrandbits(80), rng.getrandbits(79)

    def keyed(**kw):
        values = dict(mode=DelayMode.KEYED, mask_width=rng.randrange(1, 4),
                      period=rng.randrange(2, 5), pulse_width=1, key=key, iv=iv)
        values.update(kw)
        return Settings(**values).check()

    run = 0
    while len(expected) < KEYED_PULSES:
        # Stopped: write a new key and IV and wait for the keystream (the model's load of it)
        key, iv = rng.getrandbits(80), rng.getrandbits(79)
        first = keyed()
        tb.drive(first)
        tb.drive_keying(key, iv)
        dut.rekey.value = 1
        await tb.edge()
        dut.rekey.value = 0
        await ClockCycles(dut.clk, 100)
        restarts.write(key=key, iv=iv)
        restarts.load()
        ivs.append((int(dut.iv.value), restarts.iv))
        enable = await tb.edge()
        dut.enable.value = 1
        updates = []
        current = first
        for _ in range(12):
            await ClockCycles(dut.clk, rng.randrange(200, 3000))
            choice = rng.random()
            if choice < 0.3:
                key, iv = rng.getrandbits(80), rng.getrandbits(79)
                tb.drive_keying(key, iv)
                dut.rekey.value = 1
                await tb.edge()
                dut.rekey.value = 0
                current = keyed()
            elif choice < 0.8:
                current = keyed()
            else:
                current = Settings(mode=rng.choice([DelayMode.OFF, DelayMode.MASKED]),
                                   mask_width=3, seed=rng.randrange(1, 1 << 32), period=4,
                                   pulse_width=1, key=key, iv=iv).check()
            tb.drive(current)
            dut.update.value = 1
            # (high in the cycle that this edge ends, as the model counts)
            updates.append((await tb.edge() - 1, current))
            dut.update.value = 0
        await ClockCycles(dut.clk, 500)
        dut.enable.value = 0
        end = await tb.edge() - 1      # (low from the cycle this edge ends)
        expected += simulate(first, end, enable=enable, disable=end, updates=updates,
                             restarts=restarts)
        # stopped, the source loads again: the next IV if used (in keyed mode)
        restarts.load(keyed=current.keyed)
        await ClockCycles(dut.clk, 100)
        ivs.append((int(dut.iv.value), restarts.iv))
        run += 1
    tb.stop_monitors()
    got = [(f, d, i) for f, d, i in tb.fires]
    want = [(f, d, i) for f, d, _, i in expected]
    mismatches = [(k, g, w) for k, (g, w) in enumerate(zip(got, want)) if g != w]
    assert not mismatches, f"{len(mismatches)} mismatches, first {mismatches[:3]}"
    assert len(got) == len(want), (len(got), len(want))
    assert all(a == b for a, b in ivs), ivs
    dut._log.info("%d keyed pulses compared over %d runs", len(want), run)
    assert len(want) >= KEYED_PULSES
