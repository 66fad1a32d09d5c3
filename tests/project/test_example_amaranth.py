"""The Amaranth example (``examples/amaranth_delay_core/``): a user's own top level around the
delay core, with the user's own registers and TDC.

* In Amaranth's simulator, its laser trigger and TDC start against the bit-exact model of the
  delay core (:func:`fliss.sim.models.scheduler.simulate`), pulse for pulse, in several delay
  modes and across a register write while running; and its TDC against photons injected at known
  delays after each (delayed) laser pulse: each must be measured at that delay, with its pulse.
* Its imports: only the public API of ``fliss.hdl`` (names in ``__all__``), as from a wheel.
* Built for the iCEBreaker, timing met at its clock: only with ``FLISS_BUILD_BOARDS=1``
  (``make test-boards``), as ``tests/boards/test_boards.py``.
"""

import ast
import importlib
import os
import random
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from fliss.hdl.delay import DelayMode
from fliss.sim.models.scheduler import LATENCY, Settings, simulate
from simulation import simulate as run_simulation


EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "amaranth_delay_core"

#: The example's clock in the simulations, in Hz (it sets nothing in the logic).
CLOCK_HZ = 48_000_000

BUILD_BOARDS = os.environ.get("FLISS_BUILD_BOARDS") == "1"


@pytest.fixture
def example(monkeypatch):
    """The example's modules, imported from its folder as a user runs them."""
    monkeypatch.syspath_prepend(str(EXAMPLE))
    return {name: importlib.import_module(name)
            for name in ("ranger_tdc", "ranger_registers", "ranger", "ranger_board")}


def registers_of(settings, window=(10, 20)):
    """The example's register values for the model's ``settings``."""
    return dict(enable=1, mode=DelayMode(settings.mode).value, length=settings.length,
                mask_width=settings.mask_width, seed=settings.seed, period=settings.period,
                grid=int(settings.grid), pulse_width=settings.pulse_width,
                window_start=window[0], window_end=window[1])


def plan_photons(starts, rng, early=True):
    """Photon pin waveform for the TDC starts ``starts`` (cycles, from the model): after each
    start but the last, one photon at a random delay ``D`` that leaves the pin low for 2 cycles
    before the next start's photon; with ``early``, one more in cycles 0 and 1, before any
    start. Returns the pin levels by cycle, the planned (start, D, pulse) and the number of
    photons the TDC cannot measure (the early one)."""
    pin = np.zeros(starts[-1] + 8, dtype=bool)
    planned = []
    last_low = 0            # first cycle the pin may go high again
    if early:
        pin[0:2] = True
        last_low = 4
    for index, (start, following) in enumerate(zip(starts, starts[1:])):
        low = max(0, last_low - start)
        high = following - start - 4
        if high < low:
            continue
        delay = rng.randint(low, high)
        pin[start + delay:start + delay + 2] = True
        last_low = start + delay + 4
        planned.append((start, delay, index))
    return pin, planned, int(early)


def run_ranger(example, settings, *, writes=(), seed=1, cycles=None, plan=plan_photons):
    """Run the example's top level with ``settings`` in its registers from reset and the
    register ``writes`` ((cycle, address, value, the settings after it, or None if it is
    refused)); photons planned from the model's starts by ``plan`` (as :func:`plan_photons`).
    Returns the laser trace, TDC start cycles, measurements (cycle, cycles, pulse) and the
    model's pulses, the photon plan, and the counters at the end."""
    updates = [(cycle + 1, new) for cycle, _, _, new in writes if new is not None]
    model = simulate(settings, cycles - 16, updates=updates, enable=0)
    starts = [fire + LATENCY for fire, *_ in model]
    pin, planned, unmeasured = plan(starts, random.Random(seed))
    dut = example["ranger"].Ranger(CLOCK_HZ, registers_of(settings))
    laser, near, start_cycles, measured = [], [], [], []
    writes_at = {cycle: (address, value) for cycle, address, value, _ in writes}
    counters = {}

    async def testbench(ctx):
        for cycle in range(cycles):
            ctx.set(dut.photon, bool(pin[cycle]) if cycle < len(pin) else False)
            write = writes_at.get(cycle)
            ctx.set(dut.write.valid, write is not None)
            if write is not None:
                ctx.set(dut.write.payload, {"address": write[0], "data": write[1]})
            laser.append(ctx.get(dut.laser))
            near.append(ctx.get(dut.near))
            if ctx.get(dut.tdc_start):
                start_cycles.append(cycle)
            if ctx.get(dut.measurements.valid):
                payload = ctx.get(dut.measurements.payload)
                measured.append((cycle, payload.cycles, payload.pulse))
            await ctx.tick()
        counters.update(dropped=ctx.get(dut.dropped), refused=ctx.get(dut.refused))

    run_simulation(dut, testbench, clock_hz=CLOCK_HZ)
    return dict(laser=np.array(laser), near=near, starts=start_cycles, measured=measured, model=model,
                planned=planned, unmeasured=unmeasured, **counters)


def laser_pulses(laser):
    """(rising edge cycle, width) of each laser pulse in a trace."""
    edges = np.diff(np.concatenate(([0], laser, [0])).astype(int))
    rises, falls = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return list(zip(rises.tolist(), (falls - rises).tolist()))


def check_run(run):
    """The run's pulses are the model's, and every photon is measured at its planned delay."""
    model = run["model"]
    # The laser rises, for its width, and the TDC starts, LATENCY cycles after each fire
    assert laser_pulses(run["laser"])[:len(model)] == \
        [(fire + LATENCY, width) for fire, _, width, _ in model]
    assert run["starts"][:len(model)] == [fire + LATENCY for fire, *_ in model]
    # Each photon, sent D cycles after the laser's rising edge of pulse k, is measured as D
    # cycles of pulse k, 3 cycles after the pin rose (two synchroniser stages, one register);
    # the photon before any start is dropped and counted
    expected = [(start + delay + 3, delay, index) for start, delay, index in run["planned"]]
    assert run["measured"] == expected
    assert run["dropped"] == run["unmeasured"]
    # `near`, from the cycle after each measurement: within the registers' window of 10 to 20
    assert [run["near"][cycle + 1] for cycle, *_ in expected] == \
        [10 <= delay <= 20 for _, delay, _ in expected]
    assert len(model) >= 200 and len(expected) + run["unmeasured"] >= 0.9 * len(model)


@pytest.mark.parametrize("settings", [
    Settings(mode=DelayMode.MSEQ, length=5, seed=19, period=40, pulse_width=2),
    Settings(mode=DelayMode.MASKED, mask_width=4, seed=0xACE1, period=30, grid=True,
             pulse_width=3),
    Settings(mode=DelayMode.OFF, period=25, pulse_width=1),
], ids=["mseq-interval", "masked-grid", "off"])
def test_example_against_model(example, settings):
    settings.check()
    run = run_ranger(example, settings, cycles=12_000, seed=settings.seed)
    check_run(run)
    # the delays are those of the mode: the TDC starts are not evenly spaced unless it is off
    gaps = set(np.diff(run["starts"]).tolist())
    assert (len(gaps) == 1) == (settings.mode == DelayMode.OFF)


def plan_at_starts(starts, rng):
    """Photons just before each TDC start: 1 or 2 cycles before (the TDC sees them after the
    start, and drops them), or 3 (seen just before it: D = the gap - 3 after the start before,
    of that pulse)."""
    pin = np.zeros(starts[-1] + 8, dtype=bool)
    planned, unmeasured = [], 0
    for index, (start, following) in enumerate(zip(starts, starts[1:])):
        early = 1 + index % 3
        pin[following - early:following - early + 2] = True
        if early == 3:
            planned.append((start, following - start - 3, index))
        else:
            unmeasured += 1
    return pin, planned, unmeasured


def test_example_tdc_at_the_starts(example):
    # The TDC's edge: a photon seen after the next start but sent before it
    settings = Settings(mode=DelayMode.MSEQ, length=4, seed=5, period=20, pulse_width=1)
    run = run_ranger(example, settings, cycles=8_000, plan=plan_at_starts)
    check_run(run)
    assert run["unmeasured"] > 100 and len(run["planned"]) > 50


def test_example_register_write_while_running(example):
    # A write of the mode register while running: the core takes it from its next frame and
    # restarts the sequence from the seed, as the model says for an update a cycle later
    # (the register holds the new value then, and the block strobes update).
    before = Settings(mode=DelayMode.MSEQ, length=5, mask_width=5, seed=7, period=40,
                      pulse_width=2)
    after = replace(before, mode=DelayMode.MASKED)
    mode_address = [name for name, _ in example["ranger_registers"].REGISTERS].index("mode")
    writes = [(5003, mode_address, DelayMode.MASKED.value, after)]
    run = run_ranger(example, before, writes=writes, cycles=12_000)
    check_run(run)
    switch = next(i for i, (fire, *_) in enumerate(run["model"]) if fire > 5004)
    assert 50 < switch < len(run["model"]) - 50
    assert run["refused"] == 0


def test_example_refuses_writes(example):
    # Writes past the table or too wide for their register change nothing and are counted
    settings = Settings(mode=DelayMode.MSEQ, length=4, seed=3, period=30, pulse_width=1)
    names = [name for name, _ in example["ranger_registers"].REGISTERS]
    writes = [(100, len(names), 1, None),
              (200, names.index("pulse_width"), 256, None),
              (300, names.index("length"), 64, None)]
    run = run_ranger(example, settings, writes=writes, cycles=8_000)
    check_run(run)
    assert run["refused"] == 3


@pytest.mark.parametrize("change, message", [
    (dict(pulse_width=40), "Register reset values: pulse_width (40 cycles) must be shorter "
                           "than period (40 cycles)"),
    (dict(seed=32), "Register reset values: seed must be below 2**length = 32 for the mseq "
                    "source"),
    (dict(window_end=4096), "Register reset values: window_end (4096) does not fit its 12 bits"),
    (dict(length=1), "Register reset values: length must be an integer from 2 to 32, not 1"),
])
def test_example_registers_refuse_reset_values(example, construction_error, change, message):
    values = registers_of(Settings(mode=DelayMode.MSEQ, length=5, seed=1, period=40))
    registers = example["ranger_registers"].RangerRegisters
    assert construction_error(lambda: registers({**values, **change})) == message


def test_example_tdc_refuses_width(example, construction_error):
    assert construction_error(lambda: example["ranger_tdc"].CounterTdc(width=3)) == \
        "TDC width must be an integer from 4 to 16 bits, not 3"


def test_example_button_steps_the_presets(example):
    # On the board, each press of the button (sampled every 2**5 cycles, one press held for
    # 100 cycles) writes the next preset into the registers: their delay settings are the
    # preset's, and the core runs again
    board_module = example["ranger_board"]
    board = board_module.RangerOnBoard(CLOCK_HZ, debounce_s=20 / CLOCK_HZ)
    presets = board_module.presets(CLOCK_HZ)
    fields = list(presets[0])
    seen = []

    async def testbench(ctx):
        for _ in range(4):
            ctx.set(board.button, 1)
            await ctx.tick().repeat(100)
            ctx.set(board.button, 0)
            await ctx.tick().repeat(100)
            settings = ctx.get(board.ranger.registers.settings)
            seen.append(({name: int(getattr(settings, name).value if name == "mode" else
                                    getattr(settings, name)) for name in fields},
                         ctx.get(board.ranger.registers.enable), ctx.get(board.ranger.running)))

    run_simulation(board, testbench, clock_hz=CLOCK_HZ)
    assert seen == [(presets[k], 1, 1) for k in (1, 2, 0, 1)]
    assert len({tuple(sorted(preset.items())) for preset in presets}) == 3


def _fliss_imports(path):
    # (module, name) of every `from fliss... import name` and `import fliss...` of a file
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("fliss"):
            yield from ((node.module, alias.name) for alias in node.names)
        elif isinstance(node, ast.Import):
            yield from ((alias.name, None) for alias in node.names
                        if alias.name.startswith("fliss"))


def test_example_uses_only_public_api():
    # A user's design imports fliss.hdl's public names (those in a module's __all__), and the
    # build script fliss.boards.build's; nothing by a path of the checkout.
    files = sorted(EXAMPLE.glob("*.py"))
    assert {path.name for path in files} >= {"ranger.py", "ranger_tdc.py", "ranger_registers.py",
                                            "ranger_board.py", "ranger_presets.py",
                                            "build_icebreaker.py"}
    found = []
    for path in files:
        text = path.read_text()
        assert "sys.path" not in text and "__file__" not in text, path.name
        for module, name in _fliss_imports(path):
            found.append(module)
            assert module.startswith("fliss.hdl") or module == "fliss.boards.build", \
                (path.name, module)
            public = getattr(importlib.import_module(module), "__all__", ())
            assert name in public, f"{path.name}: {name} is not in {module}.__all__"
    assert "fliss.hdl.delay" in found


@pytest.mark.skipif(not BUILD_BOARDS, reason="board builds take minutes: set "
                                             "FLISS_BUILD_BOARDS=1 to run them")
def test_example_builds_for_icebreaker(example, monkeypatch, tmp_path):
    pytest.importorskip("amaranth_boards", reason="needs the boards extra")
    build = importlib.import_module("build_icebreaker")
    result = build.build(build_dir=tmp_path / "icebreaker")
    print(result.summary())
    assert result.bitstream.exists()
    assert result.constrained, f"nextpnr checked {result.constraint_mhz}, not the clock"
    assert 0 < result.utilisation["LUT"][0] <= result.utilisation["LUT"][1]
    assert 0 < result.utilisation["FF"][0] <= result.utilisation["FF"][1]
    assert result.timing_met, result.summary()
