"""Histogram engine: gateware against the model, one event per clock (dual-port banks) or every
other clock (single-port banks), bank swaps, readout."""

import warnings

import numpy as np
import pytest
from amaranth.hdl import Fragment, Instance, UnusedElaboratable

from fliss.hdl.histogram.engine import Histogram, COUNT_WIDTH
from fliss.hdl.histogram.readout import readout_cycles_per_bin
from fliss.hdl.spram import SinglePortRam
from fliss.sim.models import histogram as model

from simulation import simulate

from histogram_bench import (BANK_BITS, check_against_model, hazard_stimulus, hits,
                             run_histogram, spaced)


@pytest.mark.parametrize("read_tree", [None, True])
def test_one_event_per_clock_matches_model(read_tree):
    # 8192 bins in RAM, shift 5: 256 bins read out per frame, 1536 cycles of readout per frame.
    # Each bank one memory (as simulated), or its 8 blocks and their read tree (as on an ECP5).
    rng = np.random.default_rng(2019)
    cycles, integration, shift = 6_000, 1_800, 5
    valid, timestamps = hazard_stimulus(rng, cycles, bins=256, shift=shift, gaps=False)
    dut = Histogram(bank_bits=BANK_BITS, read_tree=read_tree)
    frames, result = run_histogram(dut, valid, timestamps, integration=integration, shift=shift)
    check_against_model(frames, result, valid, timestamps, integration=integration,
                        shift=shift, bank_bits=BANK_BITS)
    # the stimulus really hit the hazards: same bin one and two cycles apart
    bins = timestamps >> shift
    assert np.count_nonzero(bins[1:] == bins[:-1]) > 1000
    assert np.count_nonzero((bins[2:] == bins[:-2]) & (bins[1:-1] != bins[2:])) > 500


def test_single_port_every_other_clock_matches_model():
    # Single-port banks, 8192 bins, shift 5, events two to six cycles apart (mostly two): same
    # bin back to back (forwarded or from the RAM, depending on the read slots), A,B,A, runs.
    rng = np.random.default_rng(2020)
    integration, shift = 1_800, 5
    valid, timestamps = hazard_stimulus(rng, 3_000, bins=256, shift=shift, gaps=False)
    valid, timestamps = spaced(rng, valid, timestamps)
    dut = Histogram(bank_bits=BANK_BITS, ram="single")
    assert dut.latency == 8 and dut.readout_cycles_per_bin == 4
    assert dut.init_cycles == 8192 and dut.min_event_spacing == 2
    frames, result = run_histogram(dut, valid, timestamps, integration=integration, shift=shift)
    check_against_model(frames, result, valid, timestamps, integration=integration,
                        shift=shift, bank_bits=BANK_BITS)
    assert hits(valid, timestamps, shift, 2) > 500
    assert hits(valid, timestamps, shift, 3) > 50
    events = timestamps[valid] >> shift
    assert np.count_nonzero((events[2:] == events[:-2]) & (events[1:-1] != events[2:])) > 200


@pytest.mark.parametrize("ram", ["dual", "single"])
def test_gaps_overflow_and_slow_reader(ram):
    # 128 bins in RAM and no shift: timestamps from 128 up overflow and are counted. The reader
    # is ready in half of the cycles and still keeps up with the frames. The banks start with
    # garbage: the single-port engine clears them after reset.
    rng = np.random.default_rng(7)
    cycles, integration, shift, bank_bits = 4_000, 1_300, 0, 7
    valid, timestamps = hazard_stimulus(rng, cycles, bins=128, shift=shift, gaps=True)
    timestamps[rng.random(cycles) < 0.1] = rng.integers(128, 8192)
    if ram == "single":
        valid, timestamps = spaced(rng, valid, timestamps)
    ready_pattern = rng.random(100_000) < 0.5
    dut = Histogram(bank_bits=bank_bits, ram=ram)
    frames, result = run_histogram(dut, valid, timestamps, integration=integration, shift=shift,
                                   ready=lambda cycle: ready_pattern[cycle],
                                   garbage=rng if ram == "single" else None)
    check_against_model(frames, result, valid, timestamps, integration=integration,
                        shift=shift, bank_bits=bank_bits)
    assert result["overflow"] > 100


@pytest.mark.parametrize("ram", ["dual", "single"])
def test_disable_on_frame_boundary(ram):
    # enable falls exactly where a frame starts: that frame is read out empty, in the model too
    rng = np.random.default_rng(5)
    cycles, integration, shift = 1 + 3 * 900, 900, 6
    valid, timestamps = hazard_stimulus(rng, cycles, bins=128, shift=shift, gaps=False)
    if ram == "single":
        valid, timestamps = spaced(rng, valid, timestamps, length=cycles)
    dut = Histogram(bank_bits=BANK_BITS, ram=ram)
    frames, result = run_histogram(dut, valid, timestamps, integration=integration, shift=shift)
    check_against_model(frames, result, valid, timestamps, integration=integration,
                        shift=shift, bank_bits=BANK_BITS)
    assert len(frames) == 4 and frames[3][0].sum() == 0
    assert frames[2][0].sum() == np.count_nonzero(valid[1 + 2 * integration:]) > 150


@pytest.mark.parametrize("ram", ["dual", "single"])
def test_counts_saturate(ram):
    # Bins preloaded near 2**16 - 1 (as after a long acquisition), then hit back to back:
    # counts stop at 65535, through the RAM path and through the forwarding paths.
    count_max = (1 << COUNT_WIDTH) - 1
    dut = Histogram(bank_bits=4, ram=ram)
    shift = 9
    preload = np.zeros(16, dtype=np.int64)
    preload[[3, 5, 7, 9]] = count_max - 2, count_max, count_max - 1, count_max - 4
    bins = [3, 3, 3, 3, 3, 5, 7, 9, 7, 9, 7, 9, 7, 9, 1, 9, 9, 9, 9]
    stream = bins + [None] * 3 + [5, 9, None, None, 9, 3]
    if ram == "single":
        # two cycles apart, sometimes three: forwarded, or read after the write
        spread = []
        for k, value in enumerate(stream):
            spread += [value] + [None] * (1 + (k % 5 == 4))
        stream = spread
    stream = np.array(stream, dtype=object)
    frames = []

    async def stimulus(ctx):
        if dut.init_cycles:
            await ctx.tick().repeat(dut.init_cycles)
        for index, value in enumerate(preload):
            ctx.set(dut.banks[0].data[index], int(value))
        ctx.set(dut.settings.integration, 1000)
        ctx.set(dut.settings.bin_shift, shift)
        ctx.set(dut.enable, 1)
        await ctx.tick()
        for value in stream:
            ctx.set(dut.events.valid, value is not None)
            ctx.set(dut.events.payload.timestamp, ((value or 0) << shift) + 17)
            await ctx.tick()
        ctx.set(dut.events.valid, 0)
        ctx.set(dut.enable, 0)
        ctx.set(dut.readout.ready, 1)
        counts = []
        for _ in range(200):
            _, _, got, count, last = await ctx.tick().sample(
                dut.readout.valid, dut.readout.payload.count, dut.readout.payload.last)
            if got:
                counts.append(count)
                if last:
                    break
        frames.append(counts)

    simulate(dut, stimulus)
    hits = np.bincount([v for v in stream if v is not None], minlength=16)
    want = np.minimum(preload + hits, count_max)
    assert frames[0] == list(want)
    assert want[3] == want[5] == want[7] == want[9] == count_max
    # the model saturates the same way (with a 16-bit count, from zero)
    counts, _, _ = model.histogram(np.full(70_000, 3 << shift), shift=shift, bank_bits=4)
    assert counts[0, 3] == count_max and counts.sum() == count_max


@pytest.mark.parametrize("ram, read_tree", [("dual", None), ("dual", True), ("single", None)])
def test_busy_reader_drops_are_counted(ram, read_tree):
    # The reader stalls for a long time: the engine waits for the bank with `filling` low,
    # drops and counts the events that arrive meanwhile, and every frame holds exactly the
    # events of its own fill window.
    rng = np.random.default_rng(3)
    dut = Histogram(bank_bits=BANK_BITS, ram=ram, read_tree=read_tree)
    # the frames' timing scales with the readout's cycles per bin (4, or 6 with read stages)
    scale = dut.readout_cycles_per_bin / readout_cycles_per_bin(0)
    cycles, integration, shift = int(3_000 * scale), int(600 * scale), 6
    valid, timestamps = hazard_stimulus(rng, cycles, bins=128, shift=shift, gaps=False)
    if ram == "single":
        valid, timestamps = spaced(rng, valid, timestamps, length=cycles)
    filling = np.zeros(cycles + 5000, dtype=bool)

    async def probe(ctx):
        if dut.init_cycles:
            await ctx.tick().repeat(dut.init_cycles)   # cycle 0 of the stimulus
        cycle = 0
        while True:
            _, _, f = await ctx.tick().sample(dut.filling)
            filling[cycle] = f
            cycle += 1

    def stall_at(cycle):
        cycle -= dut.init_cycles
        return not (700 * scale <= cycle < 1_000 * scale or 1_500 * scale <= cycle < 1_800 * scale)

    frames, result = run_histogram(dut, valid, timestamps, integration=integration, shift=shift,
                                   ready=stall_at, probe=probe)
    # Fill windows from the observed `filling`: a frame ends after `integration` filling
    # cycles (back to back frames) or where `filling` falls.
    window = np.flatnonzero(filling[:cycles])
    assert window[0] == 1
    breaks = np.flatnonzero(np.diff(window) != 1) + 1
    runs = np.split(window, breaks)
    windows = [chunk for run in runs for chunk in np.split(run, np.arange(integration, len(run),
                                                                          integration))]
    assert len(runs) >= 3            # the engine had to wait at least twice
    assert len(frames) == len(windows)
    for (counts, _), w in zip(frames, windows):
        inside = valid[w]
        want, _, _ = model.histogram(timestamps[w][inside], shift=shift, bank_bits=BANK_BITS)
        np.testing.assert_array_equal(counts, want.ravel())
    counted = sum(int(f.sum()) for f, _ in frames)
    expected_drops = int(np.count_nonzero(valid & ~filling[:cycles]))
    assert result["dropped"] == expected_drops > (300 if ram == "dual" else 100)
    assert result["dropped_busy"] == 0
    assert counted + result["dropped"] == int(valid.sum())


def test_single_port_events_too_close_are_counted():
    # Events one cycle apart (too close for single-port banks) among events two or more apart:
    # the engine takes an event unless it took one in the cycle before; the others are counted
    # in `dropped_busy` and `dropped`. The frames hold exactly the events taken.
    rng = np.random.default_rng(11)
    cycles, integration, shift, bank_bits = 3_000, 900, 0, 7
    _, timestamps = hazard_stimulus(rng, cycles, bins=128, shift=shift, gaps=False)
    valid = rng.random(cycles) < 0.6            # many events one cycle apart, runs of them too
    valid[rng.integers(cycles, size=20)] = False
    dut = Histogram(bank_bits=bank_bits, ram="single")
    frames, result = run_histogram(dut, valid, timestamps, integration=integration, shift=shift,
                                   garbage=rng)
    # Independently: frames fill from cycle 1 to cycle `cycles - 1` (enable falls at `cycles`)
    taken = np.zeros(cycles, dtype=bool)
    for cycle in np.flatnonzero(valid):
        taken[cycle] = 1 <= cycle and not (cycle >= 1 and taken[cycle - 1])
    busy = valid & ~taken & (np.arange(cycles) >= 1)
    expected, overflow, _, _ = model.frames(np.flatnonzero(taken), timestamps[taken],
                                            integration=integration, enable=0, disable=cycles,
                                            shift=shift, bank_bits=bank_bits)
    assert len(frames) == len(expected) >= 4
    for (counts, _), want in zip(frames, expected):
        np.testing.assert_array_equal(counts, want.ravel())
    assert result["overflow"] == overflow > 100
    assert result["dropped_busy"] == int(busy.sum()) > 300
    assert result["dropped"] == int(busy.sum()) + int(valid[0])
    assert sum(int(f.sum()) for f, _ in frames) + result["overflow"] + result["dropped"] == \
        int(valid.sum())
    assert hits(taken, timestamps, shift, 2) > 100


def test_single_port_clears_banks_after_reset():
    # `enable` high from reset: the first frame starts once the banks are cleared, as if
    # `enable` rose in cycle `init_cycles`; events before are dropped; no garbage is read out.
    rng = np.random.default_rng(13)
    integration, shift, bank_bits = 900, 0, 7
    dut = Histogram(bank_bits=bank_bits, ram="single")
    start = dut.init_cycles
    assert start == 128
    valid, timestamps = hazard_stimulus(rng, 1_200, bins=128, shift=shift, gaps=False)
    valid, timestamps = spaced(rng, valid, timestamps, length=start + 3 * integration)
    valid[start - 6:start + 6] = np.arange(12) % 2 == 0    # around the first frame start
    filling = []

    async def probe(ctx):
        while True:
            _, _, f = await ctx.tick().sample(dut.filling)
            filling.append(f)

    frames, result = run_histogram(dut, valid, timestamps, integration=integration, shift=shift,
                                   garbage=rng, wait_init=False, probe=probe)
    assert filling.index(1) == start + 1
    expected, overflow, dropped, _ = model.frames(
        np.flatnonzero(valid), timestamps[valid], integration=integration, enable=start,
        disable=len(valid), shift=shift, bank_bits=bank_bits)
    assert len(frames) == len(expected) == 3
    for (counts, _), want in zip(frames, expected):
        np.testing.assert_array_equal(counts, want.ravel())
    assert result["dropped"] == dropped == int(valid[:start + 1].sum())
    assert result["overflow"] == overflow
    assert result["dropped_busy"] == 0


def test_single_port_ram():
    # SinglePortRam against a dictionary: a read shows the word in the next cycle, a write
    # cycle reads nothing and the output holds, a read after a write sees the new word.
    rng = np.random.default_rng(17)
    ram = SinglePortRam(depth=64, width=16)
    ops = [(int(rng.integers(64)), bool(rng.random() < 0.5), int(rng.integers(1 << 16)))
           for _ in range(2_000)]
    ops += [(5, True, 1234), (5, False, 0), (5, True, 4321), (6, False, 0), (5, False, 0)]

    async def testbench(ctx):
        contents = {}
        out = 0
        for address, write, data in ops:
            ctx.set(ram.addr, address)
            ctx.set(ram.write_en, write)
            ctx.set(ram.write_data, data)
            await ctx.tick()
            if write:
                contents[address] = data
            else:
                out = contents.get(address, 0)
            assert ctx.get(ram.read_data) == out
        assert out == 4321

    simulate(ram, testbench)


def test_single_port_ram_spram_on_ice40_up():
    # On an iCE40 UltraPlus platform the RAM is an SB_SPRAM256KA; other shapes are refused.
    icebreaker = pytest.importorskip("amaranth_boards.icebreaker")
    platform = icebreaker.ICEBreakerPlatform()
    fragment = Fragment.get(SinglePortRam(depth=8192, width=16), platform)
    cells = [sub for sub, _, _ in fragment.subfragments if isinstance(sub, Instance)]
    assert [cell.type for cell in cells] == ["SB_SPRAM256KA"]
    assert cells[0].ports["POWEROFF"][0].value == 1
    for depth, width in ((16385, 16), (8192, 8), (8192, 32)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnusedElaboratable)
            with pytest.raises(ValueError) as info:
                Fragment.get(SinglePortRam(depth=depth, width=width), platform)
        assert str(info.value) == (f"SB_SPRAM256KA on iCE40UP5K holds up to 16384 words of 16 "
                                   f"bits, not {depth} words of {width} bits")
    # elsewhere (no platform) a generic memory
    fragment = Fragment.get(SinglePortRam(depth=8192, width=16), None)
    assert not any(isinstance(sub, Instance) for sub, _, _ in fragment.subfragments)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnusedElaboratable)
        histogram = Fragment.get(Histogram(bank_bits=14, ram="single"), platform)
    def instances(fragment):
        for sub, _, _ in fragment.subfragments:
            if isinstance(sub, Instance):
                yield sub.type
            else:
                yield from instances(sub)
    assert list(instances(histogram)) == ["SB_SPRAM256KA"] * 2


@pytest.mark.parametrize("kwargs, message", [
    ({"bank_bits": 0}, "Bank address width must be an integer from 1 to 19 bits, not 0"),
    ({"bank_bits": 20}, "Bank address width must be an integer from 1 to 19 bits, not 20"),
    ({"count_width": 15}, "Count width must be an integer from 16 to 32 bits, not 15"),
    ({"count_width": "16"}, "Count width must be an integer from 16 to 32 bits, not '16'"),
    ({"ram": "triple"}, "RAM kind must be one of 'dual', 'single', not 'triple'"),
    ({"ram": None}, "RAM kind must be one of 'dual', 'single', not None"),
    ({"ram": "single", "count_width": 17},
     "Count width must be 16 bits with single-port RAM, not 17"),
    ({"ram": "single", "count_width": 32},
     "Count width must be 16 bits with single-port RAM, not 32"),
    ({"ram": "single", "bank_bits": 20},
     "Bank address width must be an integer from 1 to 19 bits, not 20"),
])
def test_bad_parameters(kwargs, message, construction_error):
    assert construction_error(lambda: Histogram(**kwargs)) == message


@pytest.mark.parametrize("kwargs, message", [
    ({"shift": 14}, "Bin shift must be an integer from 0 to 13, not 14"),
    ({"integration": 0}, "Integration time must be from 1 to 4294967295 clock cycles, not 0"),
])
def test_bad_settings(kwargs, message):
    with pytest.raises(ValueError) as info:
        model.check_settings(**kwargs)
    assert str(info.value) == message


def test_model_by_hand():
    counts, overflow, outside = model.histogram([0, 1, 2, 3, 31, 32, 8191], shift=5,
                                                bank_bits=2)
    assert counts.tolist() == [[5, 1, 0, 0]] and overflow == 1 and outside == 0
    assert model.bins_read(0, 13) == 8192 and model.bins_read(5, 13) == 256
    assert model.bins_read(0, bank_bits=8) == 256 and model.bins_read(13) == 1
    hists, overflow, dropped, outside = model.frames(
        [0, 1, 2, 3, 4, 5, 9], [1, 1, 2, 2, 2, 7, 7], integration=3, enable=0, disable=9,
        bank_bits=3)
    # frames start at cycles 1, 4, 7; the events of cycles 0 and 9 are outside every frame
    assert [h.tolist() for h in hists] == [[[0, 1, 2, 0, 0, 0, 0, 0]],
                                           [[0, 0, 1, 0, 0, 0, 0, 1]], [[0] * 8]]
    assert overflow == 0 and dropped == 2 and outside == 0


@pytest.mark.parametrize("ram", ["dual", "single"])
def test_shortest_frame_without_dead_time(ram):
    # With a reader that is always ready, frames follow each other without dead time if
    # `integration` is at least c n + latency + 3 cycles (n bins read out, c cycles per bin),
    # and not with one cycle less: `latency` and `readout_cycles_per_bin` are what the gateware does.
    dut = Histogram(bank_bits=4, ram=ram)
    shortest = dut.readout_cycles_per_bin * 16 + dut.latency + 3
    lows = {}

    async def testbench(ctx):
        ctx.set(dut.readout.ready, 1)
        if dut.init_cycles:
            await ctx.tick().repeat(dut.init_cycles)
        for integration in (shortest, shortest - 1):
            ctx.set(dut.settings.integration, integration)
            ctx.set(dut.enable, 1)
            await ctx.tick().repeat(2)
            filling = []
            for _ in range(6 * integration):
                _, _, f = await ctx.tick().sample(dut.filling)
                filling.append(f)
            lows[integration] = filling.count(0)
            ctx.set(dut.enable, 0)
            await ctx.tick().repeat(4 * integration)

    simulate(dut, testbench)
    assert lows[shortest] == 0 and lows[shortest - 1] > 0
