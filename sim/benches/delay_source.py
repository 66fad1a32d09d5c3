"""cocotb testbench of :class:`fliss.hdl.delay.source.DelaySource` (generated Verilog).

Long registers (L = 16, 32) make delays too long to check through the scheduler in a short run,
so here the delay stream is read directly: every delay of ``TRANSFERS`` transfers (100 000 by default), with ``ready``
driven by a PRBS, is compared with :func:`fliss.sim.models.delay.delays`.
"""

import os
import random

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import ClockCycles, FallingEdge, RisingEdge

from ...hdl.clock import DEFAULT_CLOCK_HZ
from ...hdl.delay.source import Delay
from ...hdl.delay.modes import DelayMode
from ...hdl.registers import DelaySettings
from ..models.delay import delays as model_delays


CLOCK_PERIOD_PS = round(1e12 / DEFAULT_CLOCK_HZ)
#: Delays compared per test; Icarus calls into Python every cycle slowly, so its run is shorter.
TRANSFERS = int(os.environ.get("FLISS_TB_TRANSFERS", 100_000))


def settings_bits(**settings):
    """The ``settings`` port (a :class:`~fliss.hdl.registers.DelaySettings` struct) as one
    integer."""
    return DelaySettings().const(settings).as_value().value


async def check_stream(dut, mode, *, length=2, mask_width=1, seed=1, transfers=TRANSFERS):
    Clock(dut.clk, CLOCK_PERIOD_PS, unit="ps", impl="gpi").start()
    dut.rst.value = 1
    dut.delays__ready.value = 0
    dut.load.value = 0
    await ClockCycles(dut.clk, 2)
    dut.rst.value = 0
    dut.settings.value = settings_bits(mode=mode, length=length, mask_width=mask_width,
                                       seed=seed)
    dut.load.value = 1
    await RisingEdge(dut.clk)
    dut.load.value = 0
    # Scramble the settings after the load: they must have been sampled.
    dut.settings.value = settings_bits(mode=mode, length=2, mask_width=1, seed=0)

    expected = model_delays(mode, transfers, length=length, mask_width=mask_width, seed=seed)
    rng = random.Random(seed)
    got = []
    held = None
    stalls = mismatched_holds = 0
    # Drive and sample in the middle of each cycle, where everything has settled.
    await FallingEdge(dut.clk)
    while len(got) < transfers:
        ready = rng.random() < 0.75
        dut.delays__ready.value = int(ready)
        assert int(dut.delays__valid.value) == 1
        # (the delay; its hints for the scheduler may change while it waits)
        payload = Delay.from_bits(int(dut.delays__payload.value)).value
        if held is not None and payload != held:
            mismatched_holds += 1
        if ready:
            got.append(payload)
            held = None
        else:
            stalls += 1
            held = payload
        await FallingEdge(dut.clk)
    mismatches = sum(int(a != b) for a, b in zip(got, expected.tolist()))
    dut._log.info("%d delays compared, %d stalls", len(got), stalls)
    assert mismatched_holds == 0, "payload changed without a transfer"
    assert mismatches == 0, f"{mismatches} of {transfers} delays differ from the model"
    assert stalls > transfers // 10


@cocotb.test()
@cocotb.parametrize(length=[16, 32])
async def test_mseq_stream(dut, length):
    await check_stream(dut, DelayMode.MSEQ, length=length, seed=random.randrange(1, 1 << length))


@cocotb.test()
async def test_masked_stream(dut):
    await check_stream(dut, DelayMode.MASKED, mask_width=16, seed=random.randrange(1, 1 << 32))
