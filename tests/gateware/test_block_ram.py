"""RegisteredRam (hdl/block_ram.py): the generic memory's timing against a model, and the ECP5
instance's wiring (the DP16KD itself is a black box in Yosys: the board build checks the rest)."""

import random
import re

import pytest
from amaranth.hdl import Fragment, Instance
from amaranth.sim import Simulator

from fliss.hdl.block_ram import DP16KD_WIDTH, RegisteredRam
from fliss.hdl.link.cobs import CobsEncoder
from fliss.hdl.link.framing import FrameDecoder


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


def test_ecp5_ram_goes_to_its_site():
    platform = _ecp5_platform()
    ram = RegisteredRam(depth=1024, width=16)
    ram.site = "X58/Y46/EBR0"
    instance, = [f for f, *_ in Fragment.get(ram, platform).subfragments
                 if isinstance(f, Instance)]
    assert instance.attrs["BEL"] == "X58/Y46/EBR0"
    wide = RegisteredRam(depth=1024, width=32)
    wide.site = "X58/Y46/EBR0"
    with pytest.raises(ValueError, match="A site places a RAM of one block"):
        Fragment.get(wide, platform)


def _sites(fragment):
    """``{hierarchy: BEL}`` of the DP16KD instances under ``fragment``."""
    found = {}
    for sub, name, *_ in fragment.subfragments:
        if isinstance(sub, Instance) and sub.type == "DP16KD":
            found[name] = sub.attrs.get("BEL")
        elif not isinstance(sub, Instance):
            found.update({f"{name}.{k}": v for k, v in _sites(sub).items()})
    return found


def test_ulx3s_histogram_banks_sit_in_quads_spread_over_the_rows():
    # Each group of four blocks of a bank (the first level of its read tree) sits in four
    # neighbouring EBR sites of one row: the sites are worked out here from the LFE5U-85F's
    # rows (y 22, 46, 70, 82) and its quads (13 a row, EBR0 to EBR3 two columns apart).
    from fliss.hdl.histogram.dual import DualPortBanks, OR_GROUP
    platform = _ecp5_platform()
    banks = DualPortBanks(16, 16)
    sites = _sites(Fragment.get(banks, platform))
    assert len(sites) == 128 and None not in sites.values()
    assert len(set(sites.values())) == 128
    starts = {4, 13, 22, 31, 40, 49, 58, 69, 78, 87, 96, 105, 114}
    for k in range(2):
        for start in range(0, 64, OR_GROUP):
            group = [re.fullmatch(r"X(\d+)/Y(\d+)/EBR(\d)",
                                  sites[f"bank{k}_{j}.dp16kd0"]).groups()
                     for j in range(start, start + OR_GROUP)]
            (x0, y, _), *_ = group
            assert int(y) in (22, 46, 70, 82) and int(x0) in starts
            assert [(int(x), int(y_), int(n)) for x, y_, n in group] == \
                [(int(x0) + 2 * n, int(y), n) for n in range(4)]
    # spread over the four rows, eight quads a row: every third quad free (ends and middle)
    for row in (22, 46, 70, 82):
        assert sum(f"/Y{row}/" in site for site in sites.values()) == 32
    assert not any(site.startswith(tuple(f"X{x + 2 * n}/Y{row}/" for x in (4, 31, 58, 87, 114)
                                    for n in range(4) for row in (22, 46, 70, 82)))
                   for site in sites.values())
    # elaborated with no platform, the placer decides
    Fragment.get(banks, None)
    assert all(memory.site is None for bank in banks.banks for memory in bank.memories)
