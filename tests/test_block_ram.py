"""RegisteredRam (hdl/block_ram.py): the generic memory's timing against a model, and the ECP5
instance's wiring (the DP16KD itself is a black box in Yosys: the board build checks the rest)."""

import random
import re

import pytest
from amaranth.hdl import Fragment, Instance
from amaranth.sim import Simulator

from fliss.hdl.block_ram import DP16KD_WIDTH, RegisteredRam
from fliss.hdl.cobs import CobsEncoder
from fliss.hdl.framing import FrameDecoder


@pytest.mark.parametrize("output_enable", [False, True])
def test_generic_ram_reads_two_cycles_later_and_holds(output_enable):
    # A read sampled at edge k shows its word after edge k + 1 and holds while no read is
    # made (output_enable: after the next edge with `output_en` instead); writes land at their
    # edge. The model is a dict and two registers.
    ram = RegisteredRam(depth=64, width=12, output_enable=output_enable)
    rng = random.Random(5)
    steps = [(rng.random() < 0.5, rng.random() < 0.5, rng.randrange(64), rng.random() < 0.6,
              rng.randrange(64), rng.randrange(1 << 12)) for _ in range(600)]
    seen = []

    async def testbench(ctx):
        for read_en, output_en, read_addr, write_en, write_addr, write_data in steps:
            ctx.set(ram.read_en, read_en)
            if output_enable:
                ctx.set(ram.output_en, output_en)
            ctx.set(ram.read_addr, read_addr)
            ctx.set(ram.write_en, write_en and write_addr != read_addr)   # (no collisions)
            ctx.set(ram.write_addr, write_addr)
            ctx.set(ram.write_data, write_data)
            await ctx.tick()
            seen.append(ctx.get(ram.read_data))

    sim = Simulator(ram)
    sim.add_clock(1e-6)
    sim.add_testbench(testbench)
    sim.run()

    words, latch, output, expected = {}, 0, 0, []
    for read_en, output_en, read_addr, write_en, write_addr, write_data in steps:
        if output_en or not output_enable:
            output = latch                              # the output register
        if read_en:
            latch = words.get(read_addr, 0)             # the read, before this edge's write
        if write_en and write_addr != read_addr:
            words[write_addr] = write_data
        expected.append(output)
    assert seen == expected
    assert len(set(seen)) > 50


def _bit(value):
    """``(signal name, bit)`` of a one-bit slice of a signal, however nested (from its repr,
    ``(slice (slice (sig name) 0:18) 3:4)``: the starts add up)."""
    text = repr(value)
    name = re.fullmatch(r"(?:\(slice )*\(sig (\S+)\).*", text).group(1)
    starts = [int(start) for start, _ in re.findall(r" (\d+):(\d+)\)", text)]
    assert starts, text
    return name, sum(starts)


def _ecp5_platform():
    pytest.importorskip("amaranth_boards", reason="needs the boards extra: "
                        "pip install -e '.[boards]'")
    from fliss.boards.ulx3s import FlissULX3SPlatform
    return FlissULX3SPlatform()


@pytest.mark.parametrize("width,output_enable", [(16, False), (32, False), (16, True)])
def test_ecp5_ram_is_dp16kd_with_output_register(width, output_enable):
    platform = _ecp5_platform()
    ram = RegisteredRam(depth=1024, width=width, output_enable=output_enable)
    fragment = Fragment.get(ram, platform)
    instances = [f for f, *_ in fragment.subfragments if isinstance(f, Instance)]
    assert len(instances) == -(-width // DP16KD_WIDTH)
    for k, instance in enumerate(instances):
        assert instance.type == "DP16KD"
        assert instance.parameters["REGMODE_B"] == "OUTREG"
        assert instance.parameters["REGMODE_A"] == "NOREG"
        assert instance.parameters["DATA_WIDTH_A"] == instance.parameters["DATA_WIDTH_B"] == 18
        ports = {name: value for name, (value, _) in instance.ports.items()}
        # the word address on AD[13:4] of both ports, the write's byte enables on ADA[1:0]
        for n in range(10):
            assert _bit(ports[f"ADA{n + 4}"]) == _bit(ram.write_addr[n])
            assert _bit(ports[f"ADB{n + 4}"]) == _bit(ram.read_addr[n])
        assert [ports[f"ADA{n}"].value for n in range(4)] == [1, 1, 0, 0]
        low = k * DP16KD_WIDTH
        for n in range(min(DP16KD_WIDTH, width - low)):
            assert _bit(ports[f"DIA{n}"]) == _bit(ram.write_data[low + n])
            assert _bit(ports[f"DOB{n}"]) == _bit(ram.read_data[low + n])
        assert ports["WEA"] is ram.write_en and ports["CEB"] is ram.read_en
        assert ports["WEB"].value == 0
        if output_enable:
            assert ports["OCEB"] is ram.output_en
        else:
            assert ports["OCEB"].value == 1


def test_ram_refuses_bad_depth(construction_error):
    assert construction_error(lambda: RegisteredRam(depth=2048, width=16)) == \
        "Depth must be an integer from 1 to 1024, not 2048"


def _reads_through_dp16kd(block, platform, name):
    fragment = Fragment.get(block, platform)
    buffer, = [f for f, n, *_ in fragment.subfragments if n == name]
    return any(isinstance(f, Instance) and f.type == "DP16KD" for f, *_ in buffer.subfragments)


@pytest.mark.parametrize("factory, name", [(FrameDecoder, "buffer"), (CobsEncoder, "run")],
                         ids=["frame_decoder", "cobs_encoder"])
def test_link_buffers_read_through_the_output_register_on_an_ecp5(factory, name):
    platform = _ecp5_platform()
    assert _reads_through_dp16kd(factory(), platform, name)
    assert not _reads_through_dp16kd(factory(registered_read=False), platform, name)


@pytest.mark.parametrize("factory", [FrameDecoder, CobsEncoder],
                         ids=["frame_decoder", "cobs_encoder"])
def test_link_buffers_refuse_a_bad_read_choice(construction_error, factory):
    assert construction_error(lambda: factory(registered_read="yes"), TypeError) == \
        "registered_read must be None, False or True, not 'yes'"
