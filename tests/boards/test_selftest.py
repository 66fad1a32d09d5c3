"""``fliss selftest`` on the model board with a loopback (:mod:`fliss.sim.boards.loopback`): the
figures against the loopback's stated delay and jitter, a fault of each kind against its exact
line, refusals, interruptions."""

import re

import numpy as np
import pytest

from fliss.hdl.top import FlissTop
from fliss.host.board import connect
from fliss.host.calibration import calibrate
from fliss.host.cli import main
from fliss.host.selftest import (AGGRESSOR_OFFSET, CHECKS, PERIOD_CYCLES, period_cycles,
                                 selftest)
from fliss.sim.boards.loopback import Loopback
from fliss.sim.boards.model import model_board
from fliss.sim.models.delay import delays
from fliss.sim.scene import Scene

from loopback_runs import (CLOCK_HZ, FIRST_TAP_S, INPUT_S, LINE, _InterruptAfter, _KillAfter,
                           fliss, line_of, outcomes)


@pytest.mark.parametrize("jumper, delay_s, jitter_s", [
    ("laser", 1.1e-9, 3e-12),
    ("laser", 3.2e-9, 20e-12),
    ("laser", 5.7e-9, 40e-12),
])
def test_victim_loopback(jumper, delay_s, jitter_s):
    loopback = Loopback(jumper=jumper, delay_s=delay_s, jitter_s=jitter_s, line=LINE)
    with model_board(loopback=loopback) as board, connect(board.path) as client:
        nominal = selftest(client, jumper=jumper, reference=delays)
        calibrate(client, 0.3)
        before = client.registers
        result = selftest(client, jumper=jumper, reference=delays)
        after = client.registers
    assert [c.name for c in result.checks] == list(CHECKS)
    assert outcomes(nominal) == outcomes(result) == ["pass", "skipped", "pass", "pass", "pass"]
    # With the nominal table, the taps' drift from the nominal codes (a random walk of 5 ps a
    # tap) puts the time off by up to some 200 ps
    assert abs(nominal.delay_s - (delay_s + INPUT_S)) < 250e-12
    # Calibrated: the time from the hit to the line's first tap, within a tap
    assert abs(result.delay_s - (delay_s + FIRST_TAP_S)) < 25e-12
    # The jitter as the line shows it: the spread of the centres of the codes that hits about
    # the edge less the delay fall in, from the line's own thresholds (the codes are uneven)
    edges = LINE.thresholds_s
    codes = np.searchsorted(edges, np.random.default_rng(0).normal(1 / CLOCK_HZ - delay_s,
                                                                   jitter_s, 100_000))
    shown = np.std((edges[codes - 1] + edges[codes]) / 2)
    assert abs(result.jitter_s - shown) < 0.2 * shown + 4e-12
    assert line_of(result, "histogram").detail.endswith("in off, mseq, masked, keyed")
    assert result.elapsed_s < 10
    # Put back as they were; the IV reads as the IV in use, which the keyed run moved on
    assert {k: v for k, v in after.items() if before[k] != v} == {"iv0": before["iv0"] + 1}


def test_a_keyed_source_without_ivs_is_skipped_not_failed():
    # The keyed source with the last IV: the first self-test's keyed histogram uses it; the next
    # one skips keyed (it would fire no pulse), saying why, rather than fail on an empty
    # histogram
    loopback = Loopback(jumper="laser", delay_s=2.3e-9, jitter_s=10e-12, line=LINE)
    with model_board(loopback=loopback) as board, connect(board.path) as client:
        client.configure(key="0123456789abcdef0123", iv=f"{(1 << 80) - 1:#x}")
        first = selftest(client, jumper="laser", reference=delays)
        second = selftest(client, jumper="laser", reference=delays)
    assert line_of(first, "histogram").detail.endswith("in off, mseq, masked, keyed")
    assert line_of(second, "histogram").detail.endswith(
        "in off, mseq, masked (keyed skipped: the keyed source has used every IV under its key; "
        "write a new key)")
    assert outcomes(first) == outcomes(second) == ["pass", "skipped", "pass", "pass", "pass"]


def test_aggressor_loopback_shows_the_delays():
    loopback = Loopback(jumper="aggressor", delay_s=4.1e-9, jitter_s=20e-12, line=LINE)
    with model_board(loopback=loopback) as board, connect(board.path) as client:
        result = selftest(client, jumper="aggressor", reference=delays)
    assert outcomes(result) == ["pass", "pass", "skipped", "pass", "pass"]
    # (the nominal table, and a 50 ps LSB, rounded down)
    assert abs(result.delay_s - (4.1e-9 + INPUT_S)) < 250e-12
    assert line_of(result, "delays").detail.startswith("delays as the model's (")
    assert result.elapsed_s < 10


@pytest.mark.parametrize("every", [7, 3])
def test_wrong_delays_fail_with_the_first_wrong_pulse(capsys, every):
    loopback = Loopback(jumper="aggressor", wrong_delay_every=every, line=LINE)
    # The fault: every n-th delay a cycle long; the first, pulse n - 1, in mseq (seed 1)
    model = delays("mseq", every, length=4, seed=1)[every - 1]
    with model_board(loopback=loopback) as board:
        status, out, err = fliss(capsys, "selftest", "--port", board.path, "--jumper",
                                 "aggressor", "-q")
    assert status == 1
    assert f"delays       fail     in mseq, pulse {every - 1} is delayed {model + 1} cycles, " \
           f"the model's {model} (the first that differs)" in out.splitlines()
    assert err == "fliss selftest: failed: delays (passed 3 of 5)\n"


def test_link_errors_fail(capsys):
    with model_board(loopback=Loopback(), corrupt_commands_every=9) as board:
        status, out, err = fliss(capsys, "selftest", "--port", board.path, "--jumper",
                                 "laser", "-q")
        counted = {name: board.status[name] for name in ("bad_crc", "truncated", "oversize",
                                                         "bad_length") if board.status[name]}
    assert counted
    assert status == 1
    detail = ", ".join(f"{name} {count}" for name, count in counted.items())
    assert f"link         fail     {detail}" in out.splitlines()
    assert err == "fliss selftest: failed: link (passed 3 of 5)\n"


def test_no_jumper_on_the_laser(capsys):
    # The jumper is said to carry the laser, but the pin is not looped: no hits
    dark = Scene(clock_hz=CLOCK_HZ, detections_per_pulse=0, background_hz=0)
    with model_board(scene=dark, loopback=Loopback(jumper=None)) as board:
        status, out, _ = fliss(capsys, "selftest", "--port", board.path, "--jumper", "laser")
    assert status == 1
    assert out.splitlines()[1].startswith("same time    fail     no hits in ")
    assert out.splitlines()[1].endswith(" laser pulses: check the wire: is the laser output, and "
                                        "nothing else, on the photon input?")


@pytest.mark.parametrize("pad_delay_s, jitter_s", [(2.5e-9, 20e-12), (1.7e-9, 35e-12)])
def test_internal_loopback_runs_every_check(capsys, pad_delay_s, jitter_s):
    # No jumper on the fine TDC's build: the laser's pad read back, then the aggressor's for the
    # delays; the pads' delay, not the jumper's (a jumper on the pin is left out)
    loopback = Loopback(jumper="laser", delay_s=5.7e-9, pad_delay_s=pad_delay_s,
                        jitter_s=jitter_s, line=LINE)
    with model_board(loopback=loopback) as board:
        status, out, err = fliss(capsys, "selftest", "--port", board.path)
        with connect(board.path) as client:
            calibrate(client, 0.3)
            result = selftest(client, reference=delays)
    assert status == 0
    lines = out.splitlines()[1:]
    assert [line[:22] for line in lines] == [
        "same time    pass     ", "delays       pass     ", "histogram    pass     ",
        "calibration  pass     ", "link         pass     "]
    assert lines[1].startswith("delays       pass     delays as the model's (")
    assert lines[2].endswith(" in off, mseq, masked, keyed")
    assert re.fullmatch(r"fliss selftest: passed 5 of 5 in [0-9.]+ s \(loopback: internal\)",
                        err.splitlines()[-1])
    assert result.loop == "internal" and outcomes(result) == ["pass"] * 5
    # Calibrated: the pad's delay to the lines' first tap, within the widest code the jittered
    # hits fall in (three standard deviations about the edge; the two lines' codes are uneven),
    # the table's rounding and three standard deviations of the median of the hits (1.25 sigma
    # / sqrt(n)); the jitter stated
    edges = LINE.thresholds_s
    at_s = 1 / CLOCK_HZ - pad_delay_s
    near = edges[np.searchsorted(edges, at_s - 3 * jitter_s) - 1:
                 np.searchsorted(edges, at_s + 3 * jitter_s) + 1]
    hits = int(result.checks[0].detail.split()[0])
    assert abs(result.delay_s - (pad_delay_s + FIRST_TAP_S)) < \
        np.diff(near).max() + 12.5e-12 + 3 * 1.25 * jitter_s / hits ** 0.5
    assert abs(result.jitter_s - jitter_s) < 0.2 * jitter_s + 4e-12
    assert result.elapsed_s < 10


def test_raw_events_fit_the_link():
    # At the board's 3 Mbaud, one event a pulse every 800 cycles (100 kHz) is twice what the
    # link carries: the period is made longer, so the line-limited model drops nothing
    events_per_s = 168_500 / 4      # docs/protocol.md: full EVENTS packets at 12 Mbaud
    assert abs(period_cycles(CLOCK_HZ, 3_000_000) - CLOCK_HZ / (0.8 * events_per_s)) < 1.5
    assert period_cycles(CLOCK_HZ, 12_000_000) == PERIOD_CYCLES
    with model_board(line_limited=True) as board, connect(board.path) as client:
        result = selftest(client, reference=delays)
        dropped = board.status["dropped_fifo"]
    assert outcomes(result) == ["pass"] * 5 and dropped == 0
    hits, pulses = map(int, line_of(result, "same time").detail.split()[:4:3])
    assert hits == pulses
    # At least 50 ms of raw events at the longer period (the host stops the board at the first
    # block after 50 ms of its own clock: on a loaded machine that block comes later, and the
    # board has fired more; at the default period the line-limited board would have dropped)
    assert pulses > 0.8 * 0.05 * CLOCK_HZ / period_cycles(CLOCK_HZ, 3_000_000)


def test_internal_loopback_finds_wrong_delays():
    loopback = Loopback(jumper=None, wrong_delay_every=5, line=LINE)
    with model_board(loopback=loopback) as board, connect(board.path) as client:
        result = selftest(client, reference=delays)
    model = delays("mseq", 5, length=4, seed=1)[4]
    assert outcomes(result) == ["pass", "fail", "pass", "pass", "pass"]
    assert line_of(result, "delays").detail == f"in mseq, pulse 4 is delayed {model + 1} " \
                                               f"cycles, the model's {model} (the first that " \
                                               f"differs)"


def test_internal_loopback_without_the_aggressor(capsys):
    # A fine TDC's build without the aggressor reads the laser's pad only: no delays
    maxima = FlissTop(fine_tdc=True, aggressor=False).register_maxima()
    with model_board(loopback=Loopback(jumper=None, line=LINE), maxima=maxima) as board:
        status, out, err = fliss(capsys, "selftest", "--port", board.path, "-q")
    # A skipped check: not a full self-test, whatever passed
    assert status == 3
    assert err == "fliss selftest: incomplete: passed 4 of 5, 1 skipped: not a full " \
                  "self-test (loopback: internal)\n"
    lines = out.splitlines()[1:]
    assert [line[:22] for line in lines] == [
        "same time    pass     ", "delays       skipped  ", "histogram    pass     ",
        "calibration  pass     ", "link         pass     "]
    assert lines[1] == "delays       skipped  no aggressor emitter in this build"


def test_internal_loopback_without_hits(capsys):
    # The pads read back give nothing (a model whose pads are not looped: its oscillator only)
    class Unlooped(Loopback):
        def hits(self, settings):
            kind, delay_s = super().hits(settings)
            return (None, None) if settings["tdc_input"] in (2, 3) else (kind, delay_s)

    dark = Scene(clock_hz=CLOCK_HZ, detections_per_pulse=0, background_hz=0)
    with model_board(scene=dark, aggressor_detections_per_pulse=0,
                     loopback=Unlooped(jumper=None, line=LINE)) as board:
        status, out, err = fliss(capsys, "selftest", "--port", board.path)
    assert status == 1
    lines = out.splitlines()[1:]
    assert lines[0].startswith("same time    fail     no hits in ")
    assert lines[0].endswith(" laser pulses from the laser output read back at its pad")
    assert lines[1] == "delays       fail     no hits in mseq"
    assert err.splitlines()[-1] == "fliss selftest: failed: same time, delays (passed 2 of 5)"


def test_icebreaker_build_skips_what_it_cannot_run(capsys, up5k_maxima):
    # No fine TDC, so no internal loopback: with no jumper, the checks that need hits skipped
    # (advice only of what runs the check on this build: no aggressor, so no --jumper aggressor)
    reason = "no jumper, and this build has no internal loopback (the fine TDC's)"
    laser = ": loop the laser output to the photon input (--jumper laser)"
    with model_board(loopback=Loopback(), maxima=up5k_maxima) as board:
        status, out, err = fliss(capsys, "selftest", "--port", board.path, "-q")
        assert status == 3
        assert err == "fliss selftest: incomplete: passed 1 of 5, 4 skipped: not a full " \
                      "self-test (loopback: none)\n"
        assert out.splitlines()[1:] == [
            f"same time    skipped  {reason}{laser}",
            f"delays       skipped  {reason} (this build has no aggressor emitter, whose "
            f"trigger shows them)",
            f"histogram    skipped  {reason}{laser}",
            "calibration  skipped  no fine TDC in this build",
            "link         pass     no link errors, board or host"]
        # On the jumper: the coarse TDC. The laser rises in its TDC start's cycle
        # (LaserTrigger), the jumper's 3.2 ns later: the edge that closes that cycle reads the
        # pin high, and CoarseTdc stamps the cycles from the start's to that one: code 0
        with connect(board.path) as client:
            result = selftest(client, jumper="laser", reference=delays)
    assert outcomes(result) == ["pass", "skipped", "pass", "skipped", "pass"]
    # Every hit in code 0: the jitter is below the coarse TDC's bin, not 0
    assert result.delay_s == 0 and result.jitter_s is None
    assert line_of(result, "same time").detail.endswith(
        " pulses at 0.000 ns (RMS jitter < 12.500 ns, the coarse TDC's bin)")
    assert line_of(result, "delays").detail.endswith(
        "(this build has no aggressor emitter, whose trigger shows them)")
    assert line_of(result, "histogram").detail.endswith("(keyed not in this build)")
    with model_board(loopback=Loopback(jumper="aggressor"), maxima=up5k_maxima) as board, \
            connect(board.path) as client:
        result = selftest(client, jumper="aggressor", reference=delays)
    assert [c.detail for c in result.checks[:3]] == ["no aggressor emitter in this build"] * 3


@pytest.mark.parametrize("command", ["selftest", "calibrate"])
def test_unknown_port(capsys, command):
    status, out, err = fliss(capsys, command, "--port", "/dev/fliss-no-such-port")
    assert (status, out) == (1, "")
    assert err == "fliss: error: no serial port '/dev/fliss-no-such-port' (see `fliss ports`)\n"


def test_aggressor_offset_above_the_longest_delay():
    # The aggressor's hits land after their own start only if the offset exceeds every delay
    assert AGGRESSOR_OFFSET > max(delays("mseq", 15, length=4).max(),
                                  delays("masked", 1 << 12, mask_width=4).max())


def test_register_file_reads_table_data_from_the_table():
    # A READ of table_data gives the table's entry at the pointer, not the value last written
    from amaranth.sim import Simulator
    from fliss.hdl.regfile import RegisterFile
    from fliss.hdl.registers import BY_NAME, REGISTERS

    dut = RegisterFile()
    index = {r.name: n for n, r in enumerate(REGISTERS)}
    seen = {}

    async def bench(ctx):
        for value in (0x5a5, 0xfff, 0):
            ctx.set(dut.table_read, value)
            ctx.set(dut.read_address, index["table_data"])
            seen[value] = ctx.get(dut.read_data)
        ctx.set(dut.read_address, index["table_address"])
        seen["table_address"] = ctx.get(dut.read_data)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert seen == {0x5a5: 0x5a5, 0xfff: 0xfff, 0: 0,
                    "table_address": BY_NAME["table_address"].reset_value(CLOCK_HZ)}


@pytest.mark.parametrize("options, message", [
    (["--jumper", "laser"], "a jumper runs on the cocotb engine only: use --engine cocotb"),
    (["--small"], "the iCEBreaker's build runs on the cocotb engine only: use --engine cocotb"),
])
def test_virtual_board_refuses_on_the_fast_engine(capsys, options, message):
    # (refused before anything is built)
    assert main(["board", "--engine", "fast", *options]) == 1
    assert capsys.readouterr().err == f"fliss: error: {message}\n"


def test_virtual_board_small_has_no_fine_tdc(capsys):
    assert main(["board", "--engine", "cocotb", "--small", "--fine-tdc"]) == 1
    assert capsys.readouterr().err == "fliss: error: the iCEBreaker's build has no fine TDC: " \
                                      "--small or --fine-tdc, not both\n"


def test_laser_jumper_alone_is_not_a_full_selftest(capsys):
    # Every check that ran passed, but the delays were skipped: not "passed", and exit 3
    with model_board(loopback=Loopback(jumper="laser", line=LINE)) as board:
        status, out, err = fliss(capsys, "selftest", "--port", board.path, "--jumper", "laser")
    assert status == 3
    assert [line[:22] for line in out.splitlines()[1:]] == [
        "same time    pass     ", "delays       skipped  ", "histogram    pass     ",
        "calibration  pass     ", "link         pass     "]
    assert err.splitlines()[-1] == "fliss selftest: incomplete: passed 4 of 5, 1 skipped: not " \
                                   "a full self-test (loopback: laser)"


def test_the_wire_on_the_laser_said_to_be_on_the_aggressor(capsys):
    # The laser's hits come 3.2 ns after the victim's start, which the aggressor's offset of
    # 20 cycles (250 ns) puts 246.8 ns before the aggressor fired: no loopback does that
    with model_board(loopback=Loopback(jumper="laser", line=LINE)) as board:
        status, out, _ = fliss(capsys, "selftest", "--port", board.path, "--jumper",
                               "aggressor")
    assert status == 1
    same, delays_line = out.splitlines()[1:3]
    assert same.startswith("same time    fail     ")
    assert " at -246." in same
    assert same.endswith(": a loopback takes 0 to 50.000 ns; check the wire: is the "
                         "aggressor's trigger, and nothing else, on the photon input?")
    # The victim's delays seen as the aggressor's: most pulses off, and the wire named
    assert delays_line.startswith("delays       fail     in mseq, pulse ")
    assert delays_line.endswith("differ); check the wire: is the aggressor's trigger, and "
                                "nothing else, on the photon input?")


def test_an_interrupted_selftest_keeps_the_checks_finished(capsys, monkeypatch):
    import fliss.host.commands.selftest as command
    monkeypatch.setattr(command, "Progress", lambda *args, **kwargs: _InterruptAfter(2))
    with model_board(loopback=Loopback(jumper="laser", line=LINE)) as board:
        status, out, err = fliss(capsys, "selftest", "--port", board.path)
        with connect(board.path) as client:
            after = client.registers
    assert status == 130
    assert [line[:22] for line in out.splitlines()[1:]] == [
        "same time    pass     ", "histogram    pass     "]
    assert err.splitlines()[-1] == "fliss selftest: interrupted: passed 2 of 5, 3 not run: " \
                                   "not a full self-test"
    assert after["tdc_input"] == 0 and after["acquisition"] == 0     # put back


def test_a_slow_board_gets_a_selftest_it_can_finish(capsys):
    # The model board at 1/500 of real time (a simulation's pace): a real board's 0.05 s
    # histogram would take 25 s, past every wait; measured, the test shortens them
    with model_board(loopback=Loopback(jumper="laser", line=LINE), time_scale=0.002) as board:
        status, out, err = fliss(capsys, "selftest", "--port", board.path, "--jumper", "laser")
    assert status == 3, err
    assert [line[:22] for line in out.splitlines()[1:]] == [
        "same time    pass     ", "delays       skipped  ", "histogram    pass     ",
        "calibration  pass     ", "link         pass     "]
    assert "a board at 0.002 of real time" in err.splitlines()[-1]


def test_port_options_take_units(capsys):
    with model_board(loopback=Loopback(jumper=None, line=LINE)) as board:
        status = main(["selftest", "--port", board.path, "--timeout", "5s", "--baud", "3M",
                       "-q"])
    capsys.readouterr()
    assert status == 0


@pytest.mark.parametrize("outcomes_, verdict, summary", [
    (["pass"] * 5, "pass", "passed 5 of 5"),
    (["pass", "skipped", "pass", "pass", "pass"], "incomplete",
     "passed 4 of 5, 1 skipped: not a full self-test"),
    (["skipped"] * 4 + ["pass"], "incomplete", "passed 1 of 5, 4 skipped: not a full self-test"),
    (["pass", "fail", "skipped", "pass", "pass"], "fail", "failed: delays (passed 3 of 5)"),
    (["pass", "pass"], "incomplete", "passed 2 of 5, 3 not run: not a full self-test"),
])
def test_a_skipped_check_is_never_a_pass(outcomes_, verdict, summary):
    from fliss.host.checklist import Check, SelfTest
    result = SelfTest(loop="laser", checks=[Check(name, outcome, "")
                                            for name, outcome in zip(CHECKS, outcomes_)])
    assert (result.verdict, result.summary()) == (verdict, summary)
    assert result.passed == (verdict == "pass")


def test_a_histogram_of_scene_photons_fails_naming_its_share_and_the_wire(capsys):
    # --jumper laser with no wire: the hits are the scene's echo and background, their median
    # taken as the loopback's delay. The histogram's tallest bins are there, but hold far less
    # than 90 % of the counts: the line says so (it had read "the peak is at 25.000 ns ... not
    # at 25.000 ns") and names the wire, as the same-time line does.
    scene = Scene(clock_hz=CLOCK_HZ, detections_per_pulse=0.05, background_hz=1e5)
    with model_board(scene=scene, loopback=Loopback(jumper=None)) as board:
        status, out, _ = fliss(capsys, "selftest", "--port", board.path, "--jumper", "laser")
    assert status == 1
    line = next(line for line in out.splitlines() if line.startswith("histogram "))
    match = re.fullmatch(r"histogram    fail     in off (\d+)% of the counts \(not 90%\) are at "
                         r"([\d.]+) ns, the loopback's; check the wire: is the laser output, "
                         r"and nothing else, on the photon input\?", line)
    assert match is not None, line
    assert int(match.group(1)) < 90


def test_a_killed_selftest_puts_the_settings_back_and_says_so(capsys, monkeypatch):
    # kill (SIGTERM) had ended the self-test at once: no table of the checks finished, no
    # verdict, and the board left on the loopback's settings (tdc_input 2, the fine TDC)
    import fliss.host.commands.selftest as command
    monkeypatch.setattr(command, "Progress", lambda *args, **kwargs: _KillAfter(2))
    with model_board(loopback=Loopback(jumper="laser", line=LINE)) as board:
        with connect(board.path) as client:
            before = client.registers
        status, out, err = fliss(capsys, "selftest", "--port", board.path)
        with connect(board.path) as client:
            after = client.registers
    assert status == 130
    assert err.splitlines()[-1].startswith("fliss selftest: interrupted: passed ")
    # Put back, all but the IV, which reads as the IV in use (the keyed histogram used one)
    assert {name: value for name, value in after.items() if not name.startswith("iv")} == \
        {name: value for name, value in before.items() if not name.startswith("iv")}
    assert after["tdc_input"] == 0 and after["acquisition"] == 0
