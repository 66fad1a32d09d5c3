"""cocotb testbench of :class:`fliss.hdl.top.FlissTop` in depth mode, through its pins.

The sensor model of :mod:`fliss.sim.benches.top` answers the laser with photon events; the first
frame's DEPTH packet must be the depth model's (:mod:`fliss.sim.models.depth`) of the histogram of the
events the sensor model produced, byte for byte.
"""

import random

import cocotb
import numpy as np
from cocotb.simtime import get_sim_time
from cocotb.triggers import ClockCycles, Timer

from ...hdl.protocol import PacketType
from ...hdl.registers import AcquisitionMode
from ..models.depth import depth_frame
from ...protocol.depth import depth_payload, unpack_depth
from .top import TopTB


@cocotb.test()
async def test_depth_closed_loop(dut):
    """Depth mode: the first frame's DEPTH packet equals the model's of its histogram, and no
    HISTOGRAM packet is sent."""
    tb = TopTB(dut)
    await tb.start()
    shift, integration, filter, threshold = 6, 40_000, 5, 3
    await tb.write(acquisition=AcquisitionMode.DEPTH.value, delay_mode=1, length=5, seed=3,
                   bin_shift=shift, integration=integration, depth_filter=filter,
                   depth_threshold=threshold)
    await tb.command(PacketType.START)
    # Photons in the first 1500 codes only (bins 0-23 of 128): a block standing out of zeros.
    tb.start_sensor(random.Random(21), 0.6, max_code=1500, addresses=1)   # (the frame: pixel 0)
    await ClockCycles(tb.dut.clk, integration - 3000)
    tb.stop_sensor()
    await ClockCycles(tb.dut.clk, 4000)
    await tb.command(PacketType.STOP)
    packets = []
    deadline = get_sim_time("us") + 2000
    while not packets and get_sim_time("us") < deadline:
        tb._drain()
        packets = [p for p in tb.data_packets + tb.packets if p.type == PacketType.DEPTH]
        await Timer(20, unit="us")
    assert packets, "no DEPTH packet"
    assert not [p for p in tb.data_packets + tb.packets if p.type == PacketType.HISTOGRAM]
    counts = np.bincount(np.array([e[0] for e in tb.sensor_events]) >> shift,
                         minlength=8192 >> shift)
    assert len(tb.sensor_events) > 100
    records = depth_frame(counts[None], shift=shift, filter=filter, threshold=threshold)
    want = depth_payload(records, frame=0, first_pixel=0, pixel_bits=0, shift=shift,
                         filter=filter, threshold=threshold)
    assert packets[0].payload == want, (unpack_depth(packets[0].payload), unpack_depth(want))
    assert records["detected"][0] and records["position"][0] < 24 * 16
    dut._log.info("DEPTH packet of %d events equals the model's: %s", len(tb.sensor_events),
                  records)
