"""The fine TDC's gateware against its model, bit for bit, with the model lines' samples
(bubbles, metastable taps, two lines) injected; the lines' carry chains on the ECP5; the
calibration table's computation against worked cases."""

import numpy as np
import pytest

from fliss.analysis import calibration
from fliss.hdl.clock import DEFAULT_CLOCK_HZ, cycle_units
from fliss.hdl.finetdc import CODE_BITS, LATENCY, LINE_TAP_S, LINE_TAPS, LINES, TAPS, UNIT_S
from fliss.hdl.finetdc.table import nominal_table
from fliss.hdl.finetdc.tdc import FineTdc
from fliss.sim.models import finetdc as model
from simulation import simulate


PERIOD_S = 1 / DEFAULT_CLOCK_HZ


def hit_train(rng, line, hits):
    """First-stage samples per cycle for ``hits`` hits at random times and widths, some too
    close for the line to empty between them; and the number of cycles."""
    times = np.cumsum(rng.uniform(1.5, 6.0, hits)) * PERIOD_S + 5 * PERIOD_S
    widths = rng.uniform(0.5e-9, 12e-9, hits)
    cycles = int(times[-1] / PERIOD_S) + 8
    samples = np.zeros((cycles, line.total_taps), dtype=bool)
    reach = line.thresholds_s[-1] + 15e-9
    for t, width in zip(times, widths):
        first = int(np.ceil(t / PERIOD_S))
        edges = np.arange(first, min(cycles, first + int(reach / PERIOD_S) + 2))
        samples[edges] |= line.samples(edges * PERIOD_S - t, rng, width_s=width)
    return samples, cycles


def run_fine(samples, starts, pulse_index, table, lsb, raw):
    dut = FineTdc(clock_hz=DEFAULT_CLOCK_HZ)
    found = []
    read_back = []
    weights = 1 << np.arange(samples.shape[1], dtype=object)

    async def testbench(ctx):
        ctx.set(dut.lsb, lsb)
        ctx.set(dut.raw, raw)
        ctx.set(dut.address, 5)
        ctx.set(dut.enable, 1)
        # The table, from address 0 up, then three entries read back
        ctx.set(dut.table_seek, 1)
        ctx.set(dut.table_address, 0)
        for entry in table:
            ctx.set(dut.table_write, 1)
            ctx.set(dut.table_data, int(entry))
            await ctx.tick()
            ctx.set(dut.table_seek, 0)
        ctx.set(dut.table_write, 0)
        for address in (1, 17, len(table) - 1):
            ctx.set(dut.table_seek, 1)
            ctx.set(dut.table_address, address)
            await ctx.tick()
            ctx.set(dut.table_seek, 0)
            await ctx.tick().repeat(2)
            read_back.append(ctx.get(dut.table_read))
        await ctx.tick().repeat(4)
        for cycle in range(len(samples) + LATENCY + 2):
            if cycle < len(samples):
                ctx.set(dut.sampled, int(np.dot(samples[cycle], weights)))
                ctx.set(dut.tdc_start, int(starts[cycle]))
                ctx.set(dut.pulse_index, int(pulse_index[cycle]))
            else:
                ctx.set(dut.sampled, 0)
            _, _, valid, ts, over, pulse, address = await ctx.tick().sample(
                dut.captures.valid, dut.captures.event.timestamp, dut.captures.overflow,
                dut.captures.event.pulse, dut.captures.event.address)
            if valid:
                assert address == 5
                found.append({"cycle": cycle, "timestamp": ts, "overflow": bool(over),
                              "pulse": pulse})

    simulate(dut, testbench)
    return found, read_back


@pytest.mark.parametrize("lsb,raw", [(0, 0), (1, 0), (2, 0), (0, 1)])
def test_fine_tdc_matches_model(lsb, raw):
    rng = np.random.default_rng(20 + lsb + 3 * raw)
    line = model.Line(seed=7, bubble_probability=0.3, metastable_s=4e-12)
    samples, cycles = hit_train(rng, line, 700)
    # Both lines seen, and not alike: a count of one line, or of one twice, would differ
    per_line = samples.reshape(cycles, LINES, LINE_TAPS).sum(axis=2)
    assert LINES == 2 and np.count_nonzero(per_line[:, 0] != per_line[:, 1]) > 300
    starts = np.zeros(cycles, dtype=bool)
    starts[np.cumsum(rng.integers(3, 45, cycles))[:cycles // 3].clip(max=cycles - 1)] = True
    pulse_index = np.cumsum(starts) + 1000
    counts = rng.integers(50, 150, TAPS + 1)
    table = np.zeros(1 << CODE_BITS, dtype=np.int64)
    table[:TAPS + 1] = calibration.table(counts, PERIOD_S, UNIT_S)
    table[TAPS + 1:] = rng.integers(0, 4096, len(table) - TAPS - 1)
    found, read_back = run_fine(samples, starts, pulse_index, table, lsb, raw)
    expected = model.captures(samples.sum(axis=1), starts, table, clock_hz=DEFAULT_CLOCK_HZ,
                              lsb_select=lsb, raw=bool(raw), pulse_index=pulse_index)
    assert read_back == [table[1], table[17], table[-1]]
    assert len(expected) > 300
    assert sum(not e["overflow"] for e in expected) > 100
    assert [e["cycle"] for e in found] == [e["cycle"] for e in expected]
    for got, want in zip(found, expected):
        assert got["overflow"] == want["overflow"], (got, want)
        assert got["pulse"] == want["pulse"], (got, want)
        if not want["overflow"]:
            assert got["timestamp"] == want["timestamp"], (got, want)


class _Ecp5:
    # Enough of an ECP5 platform for the line to elaborate its carry chains
    family = "ecp5"

    def __init__(self):
        self.extra_files = {}

    def add_file(self, name, content):
        self.extra_files[name] = content


def test_lines_are_carry_chains_on_the_ecp5():
    # Followed from the hit along CIN <- COUT: two chains of taps // 2 + 1 cells each, every cell
    # propagating but the one that injects the hit; the first stage samples chain 0's taps,
    # then chain 1's, each from the input on (a cell's S0, then S1; the first cell's S1 only)
    from amaranth.hdl import Fragment
    from fliss.hdl.finetdc.line import CARRY_BOX, CARRY_BOX_FILE, DelayLine
    dut = DelayLine(taps=6, lines=2)
    platform = _Ecp5()
    fragment = Fragment.get(dut, platform)
    assert CARRY_BOX_FILE[0] in platform.extra_files
    cells = [sub for sub, _, _ in fragment.subfragments if getattr(sub, "type", None) == CARRY_BOX]
    assert len(cells) == 2 * (6 // 2 + 1)
    port = {id(cell): {name: value for name, (value, _) in cell.ports.items()} for cell in cells}
    after = {id(port[id(cell)]["CIN"]): cell for cell in cells}
    taps = []
    for first in [cell for cell in cells if port[id(cell)]["A0"] is dut.hit]:
        chain, cell = [], first
        while cell is not None:
            chain.append(cell)
            cell = after.get(id(port[id(cell)]["COUT"]))
        assert len(chain) == 4
        assert [c.parameters["INIT0"].value for c in chain] == [0x000A, 0xFFFF, 0xFFFF, 0xFFFF]
        sums = [port[id(c)][half] for c in chain for half in ("S0", "S1")]
        taps += sums[1:7]
    sampled = next(s for s in fragment.statements["sync"] if s.lhs.name == "sampled")
    assert len(taps) == 12 and [id(p) for p in sampled.rhs.parts] == [id(t) for t in taps]
    with pytest.raises(ValueError, match=r"^The fine TDC needs at least one delay line, not 0$"):
        DelayLine(lines=0)
    with pytest.raises(ValueError, match=r"^Raw codes up to 2 lines of 600 taps do not fit the "
                                         r"calibration table's 1024 entries$"):
        FineTdc(clock_hz=DEFAULT_CLOCK_HZ, taps=600)


def test_bubbles_leave_the_code():
    # The ones count of a sample with a bubble is that of the sample without one; in each line
    line = model.Line(seed=3, bubble_probability=1.0, metastable_s=0.0)
    tau = np.linspace(1e-9, 12e-9, 200)
    clean = model.Line(seed=3, bubble_probability=0.0, metastable_s=0.0)
    rng = np.random.default_rng(1)
    bubbled = line.samples(tau, rng)
    steps = np.diff(bubbled.reshape(len(tau), LINES, LINE_TAPS).astype(int), axis=2)
    assert np.all(np.any(steps > 0, axis=(0, 2)))     # some 0 -> 1 inside each line
    assert np.array_equal(bubbled.sum(axis=1), clean.samples(tau, rng).sum(axis=1))
    assert np.array_equal(bubbled.sum(axis=1), clean.codes(tau, rng))


def test_table_of_known_widths():
    # Codes of 10, 20, 30 and 40 ps in a 100 ps period: centres 5, 20, 45 and 80 ps; in
    # 12.5 ps units 0.4, 1.6, 3.6, 6.4 -> 0, 2, 4, 6
    counts = [100, 200, 300, 400]
    assert np.allclose(calibration.code_widths(counts, 100e-12), [10e-12, 20e-12, 30e-12,
                                                                  40e-12])
    assert np.allclose(calibration.code_centres(counts, 100e-12),
                       [5e-12, 20e-12, 45e-12, 80e-12])
    assert calibration.table(counts, 100e-12, 12.5e-12).tolist() == [0, 2, 4, 6]
    # Equal codes: no non-linearity; one code twice as wide: DNL +1 there
    assert np.allclose(calibration.dnl([0, 5, 5, 5, 5, 0]), 0)
    assert np.allclose(calibration.inl([0, 5, 5, 5, 5, 0]), 0)
    assert np.allclose(calibration.dnl([4, 4, 8, 4]), [-0.2, -0.2, 0.6, -0.2])
    # centres 2, 6, 12, 18 against 5 * (k + 1/2) = 2.5, 7.5, 12.5, 17.5
    assert np.allclose(calibration.inl([4, 4, 8, 4]), [-0.1, -0.3, -0.1, 0.1])


def test_table_refusals():
    with pytest.raises(ValueError, match=r"^A code-density histogram needs at least one hit$"):
        calibration.table([0, 0, 0], 1e-9, 1e-12)
    with pytest.raises(ValueError, match=r"^Calibration entries up to 120 do not fit 6 bits$"):
        calibration.table([1, 1], 1e-9, 6.25e-12, width=6)   # 250 and 750 ps


def test_nominal_table_and_clock():
    # codes of 35.5 / 2 ps: code 1 at 8.875 ps, code 2 at 26.625 ps, in 12.5 ps units
    assert nominal_table()[:3] == [0, 1, 2]
    assert cycle_units(80e6) == 1000 and cycle_units(100e6) == 800
    with pytest.raises(ValueError, match=r"^The fine TDC needs a clock period that is a "
                                         r"whole multiple of 12.5 ps, not 36000000.0 Hz$"):
        cycle_units(36e6)
    for clock_hz in (0, -80e6):      # no clock: the same refusal, not a division by zero
        with pytest.raises(ValueError, match=rf"^The fine TDC needs .*, not {clock_hz} Hz$"):
            cycle_units(clock_hz)


def test_calibration_meets_the_goals():
    # Two lines like nextpnr's routed one (taps of 8.4 and 62.5 ps in turn, 20 ps of variation):
    # codes of at most 30 ps on average, single-shot RMS of at most 20 ps, each code's mean error
    # within one code; without calibration, none of that. One such line alone misses the first.
    from fliss.sim.studies.finetdc import evaluate
    hops = dict(tap_s=8.4e-12, hop_taps=2, hop_s=54.1e-12, sigma_s=20e-12)
    result = evaluate(model.Line(**hops), calibration_hits=1 << 21, test_hits=200_000)
    code = result["mean_code_s"]
    assert code <= 30e-12
    assert result["full_share"] == 0
    assert result["rms_after_s"] <= 20e-12 < result["rms_before_s"]
    assert np.abs(result["code_inl_after_s"]).max() < code < np.abs(
        result["code_inl_before_s"]).max()
    one = evaluate(model.Line(taps=640, lines=1, **hops), calibration_hits=1 << 20,
                   test_hits=10_000)
    assert one["mean_code_s"] > 30e-12


def test_lines_cover_a_clock_period():
    # Each line covers the board's clock period with 10 % to spare at nextpnr's mean tap; the
    # sum of the lines' codes fits the 1024-entry table
    assert LINE_TAPS * LINE_TAP_S >= 1.1 / DEFAULT_CLOCK_HZ
    assert TAPS == LINES * LINE_TAPS < 1 << CODE_BITS == 1024
    # The model's lines too, and a line shorter than a period shows in the hits past every tap
    from fliss.sim.studies.finetdc import evaluate
    assert model.Line().line_thresholds_s[:, -1].min() >= 1.1 / DEFAULT_CLOCK_HZ
    short = evaluate(model.Line(taps=200), calibration_hits=1 << 16, test_hits=1000)
    assert 0.3 < short["full_share"] < 0.6      # (7.1 of 12.5 ns covered)


def test_model_board_fine_sources(tmp_path):
    # The model board's fine TDC: the target's peak where the sensor puts it (in seconds) at
    # 50 and 12.5 ps, and in raw codes at the nominal codes (17.75 ps each) the echo passes
    # before the next clock edge.
    from fliss.host.acquisition import capture
    from fliss.host.client import BoardClient
    from fliss.host.fileformat import read_capture
    from fliss.sim.boards.model import model_board
    counts = {}
    with model_board() as board_model, BoardClient(board_model.path, timeout_s=1) as board:
        board.identify()
        for source, lsb in ((0, 0), (2, 0), (2, 2), (3, 0)):
            board.write_registers({"tdc_source": source, "fine_lsb": lsb})
            path = tmp_path / f"{source}-{lsb}.h5"
            capture(board, path, integration_s=5e-3, acquisitions=2)
            data = read_capture(path)
            counts[source, lsb] = (np.asarray(data.histograms).sum(axis=0), data.code_s)

    def centre(key):
        # the peak: the maximum of the counts over 1 ns windows, then the centroid of the
        # counts above the background (the median over the codes in use) within 3 ns of it
        histogram, code_s = counts[key]
        used = histogram[:np.flatnonzero(histogram)[-1] + 1].astype(np.float64)
        times = np.arange(len(used)) * code_s
        width = max(1, int(round(1e-9 / code_s)))
        around = times[np.argmax(np.convolve(used, np.ones(width), mode="same"))]
        near = np.abs(times - around) < 3e-9
        signal = used[near] - np.median(used)
        return float((times[near] * signal).sum() / signal.sum())

    assert counts[2, 2][1] == 12.5e-12 and counts[3, 0][1] == 35.5e-12 / 2
    sensor = centre((0, 0))
    assert abs(sensor - 26.7e-9) < 0.5e-9
    for key in ((2, 0), (2, 2)):
        assert abs(centre(key) - sensor) < 0.2e-9, key
    # raw codes: the time from the echo to the next clock edge, at the timing model's taps
    # (the pulse's tail wraps round the cycle: a looser bound, still far from the 1.7 ns after
    # the edge that a wrong sense would give)
    before = 12.5e-9 - sensor % 12.5e-9
    assert abs(centre((3, 0)) - before) < 0.4e-9


def test_hit_source_selects_each_input():
    # Each `tdc_input` drives the line from its own input, and from no other (the oscillator is
    # the ECP5's: 0 in simulation)
    from fliss.hdl.finetdc import HitInput
    from fliss.hdl.finetdc.source import HitSource
    dut = HitSource()
    inputs = {HitInput.PIN: dut.pin, HitInput.LASER: dut.laser, HitInput.AGGRESSOR: dut.aggressor}
    seen = {}

    async def testbench(ctx):
        for select in HitInput:
            ctx.set(dut.select, select)
            for name, signal in inputs.items():
                for signal_ in inputs.values():
                    ctx.set(signal_, signal_ is signal)
                await ctx.delay(1e-9)
                seen[select, name] = ctx.get(dut.hit)

    from amaranth.sim import Simulator
    sim = Simulator(dut)        # (no clock: the selection is combinational off the ECP5)
    sim.add_testbench(testbench)
    sim.run()
    assert seen == {(select, name): int(select == name) for select in HitInput for name in inputs}


def test_table_read_back_follows_the_pointer():
    # Seeks and writes (alone, both in one cycle, back to back), then `read_data` three cycles
    # after the last strobe: the entry at the pointer, as the host's model of the table has it
    # (a READ straight after a WRITE reads the entry after the one written)
    from fliss.hdl.finetdc.table import CalibrationTable
    dut = CalibrationTable()
    rng = np.random.default_rng(11)
    table = nominal_table()
    pointer = 0
    ops = []
    for _ in range(300):
        seek = rng.random() < 0.4
        write = not seek or rng.random() < 0.5
        ops.append((seek, int(rng.integers(0, len(table))), write, int(rng.integers(0, 4096)),
                    int(rng.choice([0, 0, 3, 3, 5]))))
    expected, seen = [], []
    for seek, address, write, data, wait in ops:
        if seek:
            pointer = address
        if write:
            table[pointer] = data
            pointer = (pointer + 1) % len(table)
        if wait:
            expected.append(table[pointer])

    async def testbench(ctx):
        for seek, address, write, data, wait in ops:
            ctx.set(dut.seek, seek)
            ctx.set(dut.seek_address, address)
            ctx.set(dut.write, write)
            ctx.set(dut.write_data, data)
            await ctx.tick()
            ctx.set(dut.seek, 0)
            ctx.set(dut.write, 0)
            if wait:
                await ctx.tick().repeat(wait - 1)
                seen.append(ctx.get(dut.read_data))

    simulate(dut, testbench)
    assert len(seen) > 100
    assert seen == expected


@pytest.mark.parametrize("name, strobe, value", [("table_address", "table_seek", 517),
                                                 ("table_data", "table_write", 3001)])
def test_table_strobes_come_with_the_values_written(name, strobe, value):
    # The calibration table takes its address and data from the fine_tdc group in the cycle its
    # strobe is high: they must be the values the WRITE wrote, not the ones before it
    from amaranth.sim import Simulator
    from fliss.hdl.regfile import RegisterFile
    from fliss.hdl.registers import BY_NAME

    dut = RegisterFile()
    seen = []

    async def bench(ctx):
        ctx.set(dut.begin, 1)
        await ctx.tick()
        ctx.set(dut.begin, 0)
        ctx.set(dut.start, 1)
        ctx.set(dut.start_address, BY_NAME[name].address)
        await ctx.tick()
        ctx.set(dut.start, 0)
        ctx.set(dut.value, value)
        await ctx.tick()
        ctx.set(dut.check, 1)
        await ctx.tick()
        ctx.set(dut.check, 0)
        await ctx.tick().repeat(5)
        assert ctx.get(dut.consistent) and not ctx.get(dut.error)
        ctx.set(dut.commit, 1)
        for _ in range(4):
            await ctx.tick()
            ctx.set(dut.commit, 0)
            if ctx.get(getattr(dut, strobe)):
                seen.append(ctx.get(getattr(dut.fine_tdc, BY_NAME[name].field)))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert seen == [value]
