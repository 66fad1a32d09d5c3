"""``fliss selftest`` on the virtual board (cocotb engine, the top level in Verilator).

With the fine TDC, its delay line driven from the model (:mod:`fliss.sim.boards.fine_loopback`):
the internal loopback's delay (the trigger outputs' pads read back) and a jumper's against the
ones the driver states, every check through the gateware with no jumper, the code-density
calibration of the oscillator's hits, the table written and read back through the gateware's
registers, and the victim's delays against the reference model through the aggressor's jumper.

Without it, the coarse TDC on a jumper (:mod:`fliss.sim.boards.jumper`): every line of the
self-test through the laser's jumper and the aggressor's on the board ``make test`` builds
anyway, and through the laser's on the iCEBreaker's build (histograms only).

``make test`` runs the fine TDC's internal loopback (every check) and the coarse TDC's two
jumpers; ``make test-long`` (marker long, in CI) the self-tests that take a minute or more each:
the fine TDC's calibration, its laser's and aggressor's jumpers, the command line's own pace,
and the iCEBreaker's build.

A missing Verilator skips these tests, or fails them when ``FLISS_REQUIRE_SIMULATORS`` is set.
"""

import math
import os
import re

import numpy as np
import pytest

from fliss.hdl.clock import DEFAULT_CLOCK_HZ
from fliss.host.board import connect
from fliss.host.calibration import calibrate
from fliss.host.cli import main
from fliss.host.selftest import (CHECKS, EMPTY_SHARE, PERIOD_CYCLES, SIMULATION_DURATIONS_S,
                                 selftest)
from fliss.host.virtual import VirtualBoard
from fliss.sim.benches.runner import simulator_available
from fliss.sim.boards.loopback import JITTER_S, JUMPER_DELAY_S, PAD_DELAY_S
from fliss.sim.models.delay import delays
from fliss.sim.models.finetdc import Line


#: The driver's line (FineLoopback's default).
LINE = Line()
#: A simulated board is slower than real time: short acquisitions; the calibration's some
#: 29 000 hits (45 a code, above the check's least 25) in frames of 2 ms, each of which the
#: board simulates within the host's wait for a histogram.
DURATIONS_S = {"raw": 0.3, "histogram": 0.0005, "calibration": 0.012, "calibration_frame": 0.002}


@pytest.fixture(scope="module")
def board():
    if not simulator_available("verilator"):
        if os.environ.get("FLISS_REQUIRE_SIMULATORS"):
            pytest.fail("Verilator is missing")
        pytest.skip("Verilator is missing")
    virtual = VirtualBoard("verilator", engine="cocotb", fine_tdc=True, jumper="laser",
                           seed=3)
    virtual.start(timeout_s=1800)
    try:
        yield virtual
    finally:
        virtual.stop()


def test_internal_loopback_on_the_gateware(board):
    # No jumper: the trigger outputs' pads read back, every check (the board's jumper on the
    # photon pin is not read)
    with connect(board.path, timeout_s=10.0) as client:
        result = selftest(client, reference=delays, durations_s=DURATIONS_S)
    assert [(check.name, check.outcome) for check in result.checks] == \
        [(name, "pass") for name in CHECKS], result.table()
    assert result.loop == "internal"
    # The nominal table: the pad's delay from the line's input, within the taps' drift; the
    # jitter with the LSB's and the taps' quantisation, from some 15 hits
    assert abs(result.delay_s - (PAD_DELAY_S + LINE.offset_s)) < 250e-12
    assert JITTER_S / 2 < result.jitter_s < 2 * JITTER_S


@pytest.mark.long
def test_the_command_line_finds_the_boards_pace(board, capsys):
    # `fliss selftest --port P` as the docs say, no durations given: it measures the board's
    # pace and fits its acquisitions and waits to it (a real board's 0.05 s histogram is 4
    # million cycles, minutes here, past every wait)
    status = main(["selftest", "--port", board.path])
    out, err = capsys.readouterr()
    assert status == 0, out + err
    assert [line[:22] for line in out.splitlines()[1:]] == [
        f"{name:<11}  pass     " for name in CHECKS]
    assert re.fullmatch(r"fliss selftest: passed 5 of 5 in [0-9.]+ s \(loopback: internal, a "
                        r"board at [0-9.e-]+ of real time\)", err.splitlines()[-1]), err


@pytest.mark.long
def test_laser_jumper_on_the_gateware(board):
    with connect(board.path, timeout_s=10.0) as client:
        result = selftest(client, jumper="laser", reference=delays, durations_s=DURATIONS_S)
    outcomes = {check.name: check.outcome for check in result.checks}
    assert outcomes == {"same time": "pass", "delays": "skipped", "histogram": "pass",
                        "calibration": "pass", "link": "pass"}, result.table()
    # The nominal table: the hit's time from the line's input, within the taps' drift
    assert abs(result.delay_s - (JUMPER_DELAY_S + LINE.offset_s)) < 250e-12
    assert JITTER_S / 2 < result.jitter_s < 2 * JITTER_S


@pytest.mark.long
def test_calibration_through_the_gateware(board):
    with connect(board.path, timeout_s=10.0) as client:
        # (the table read back and compared)
        result = calibrate(client, DURATIONS_S["calibration"],
                           integration_s=DURATIONS_S["calibration_frame"])
        after = selftest(client, jumper="laser", reference=delays, durations_s=DURATIONS_S)
    assert len(result.empty_codes) <= EMPTY_SHARE * (result.last_code - result.first_code + 1)
    # Calibrated: from the hit to the lines' first tap, within the code the hit falls in and
    # the table's rounding, three standard deviations of the code density's estimate at the
    # loopback's code (the share p of the hits below it, of N: sqrt(p (1 - p) / N) of a period)
    # and three of the median of the jittered hits (1.25 sigma / sqrt(n))
    period_s = 1 / DEFAULT_CLOCK_HZ
    edges = LINE.thresholds_s
    code = np.searchsorted(edges, period_s - JUMPER_DELAY_S)
    share = (period_s - JUMPER_DELAY_S - edges[0]) / period_s
    sigma_s = period_s * (share * (1 - share) / result.counts.sum()) ** 0.5
    hits = int(after.checks[0].detail.split()[0])
    assert abs(after.delay_s - (JUMPER_DELAY_S + edges[0])) < \
        3 * sigma_s + edges[code] - edges[code - 1] + 12.5e-12 + 3 * 1.25 * JITTER_S / hits ** 0.5


@pytest.mark.long
def test_the_delays_through_the_aggressors_jumper():
    if not simulator_available("verilator"):
        pytest.skip("Verilator is missing")
    virtual = VirtualBoard("verilator", engine="cocotb", fine_tdc=True, jumper="aggressor",
                           seed=4)
    virtual.start(timeout_s=1800)
    try:
        with connect(virtual.path, timeout_s=10.0) as client:
            result = selftest(client, jumper="aggressor", reference=delays,
                              durations_s=DURATIONS_S)
    finally:
        virtual.stop()
    outcomes = {check.name: check.outcome for check in result.checks}
    assert outcomes == {"same time": "pass", "delays": "pass", "histogram": "skipped",
                        "calibration": "pass", "link": "pass"}, result.table()
    # The nominal table, a 50 ps LSB rounded down
    assert abs(result.delay_s - (JUMPER_DELAY_S + LINE.offset_s)) < 250e-12


#: The coarse TDC's code of a jumper's hit: the laser rises at the clock edge that opens its TDC
#: start's cycle (fliss.hdl.delay.laser.LaserTrigger), the jumper's copy JUMPER_DELAY_S later;
#: the first edge to read the pin high closes the cycle floor(JUMPER_DELAY_S f) after the
#: start's, and CoarseTdc stamps the cycles from the start's cycle to that one (fliss.hdl.tdc).
#: (0 for any jumper under a cycle.) The aggressor's hit is that plus its offset.
COARSE_CODE = math.floor(JUMPER_DELAY_S * DEFAULT_CLOCK_HZ)
#: What ``same time`` and ``histogram`` say of that code: no jitter within one code.
COARSE_AT = f"{COARSE_CODE / DEFAULT_CLOCK_HZ * 1e9:.3f} ns"
LASER_DELAYS = "the victim's own hits are timed from its own delayed start, so its delays do " \
               "not show: loop the aggressor's trigger to the photon input (--jumper aggressor)"


def coarse_selftest(jumper, **options):
    """The self-test's lines on a virtual board without the fine TDC, with ``jumper``."""
    if not simulator_available("verilator"):
        if os.environ.get("FLISS_REQUIRE_SIMULATORS"):
            pytest.fail("Verilator is missing")
        pytest.skip("Verilator is missing")
    virtual = VirtualBoard("verilator", engine="cocotb", jumper=jumper, seed=5, **options)
    virtual.start(timeout_s=1800)
    try:
        with connect(virtual.path, timeout_s=10.0) as client:
            # (the durations the self-test picks at the board's pace: raw acquisitions of some
            # 40 pulses, histograms of 0.5 ms)
            result = selftest(client, jumper=jumper, reference=delays)
    finally:
        virtual.stop()
    # (the table `fliss selftest` prints)
    return result, result.table().splitlines()


def hits_and_pulses(line):
    """The hits and pulses of a ``same time`` line at :data:`COARSE_AT`, or fail."""
    found = re.fullmatch(rf"same time    pass     (\d+) hits of (\d+) pulses at "
                         rf"{re.escape(COARSE_AT)} \(RMS jitter < 12\.500 ns, the coarse "
                         rf"TDC's bin\)", line)
    assert found, line
    return int(found[1]), int(found[2])


def test_coarse_tdc_on_the_lasers_jumper():
    result, lines = coarse_selftest("laser")
    hits, pulses = hits_and_pulses(lines[1])
    assert pulses >= 20 and hits == pulses, lines[1]
    assert lines[2:] == [
        f"delays       skipped  {LASER_DELAYS}",
        f"histogram    pass     peak at {COARSE_AT} in off, mseq, masked, keyed",
        "calibration  skipped  no fine TDC in this build",
        "link         pass     no link errors, board or host"]
    assert result.delay_s == COARSE_CODE / DEFAULT_CLOCK_HZ


def test_coarse_tdc_on_the_aggressors_jumper():
    # The victim's delays through the coarse TDC, pulse for pulse
    _, lines = coarse_selftest("aggressor")
    hits, pulses = hits_and_pulses(lines[1])
    assert pulses >= 20 and hits == pulses, lines[1]
    found = re.fullmatch(r"delays       pass     delays as the model's \((\d+) pulses in mseq, "
                         r"(\d+) pulses in masked\)", lines[2])
    assert found and min(int(found[1]), int(found[2])) >= 20, lines[2]
    assert lines[3:] == [
        "histogram    skipped  the photon input carries the aggressor's trigger, not the "
        "victim's laser: loop the laser output to the photon input (--jumper laser)",
        "calibration  skipped  no fine TDC in this build",
        "link         pass     no link errors, board or host"]


@pytest.mark.long
def test_coarse_tdc_on_the_icebreakers_build():
    # No raw events: `same time` from a histogram of 0.5 ms, its pulses counted from the
    # integration time (a start more or less in the window)
    result, lines = coarse_selftest("laser", small=True)
    hits, pulses = hits_and_pulses(lines[1])
    assert pulses == round(SIMULATION_DURATIONS_S["histogram"] * DEFAULT_CLOCK_HZ) // PERIOD_CYCLES
    assert abs(hits - pulses) <= 1, lines[1]
    assert lines[2:] == [
        "delays       skipped  the victim's own hits are timed from its own delayed start, so "
        "its delays do not show (this build has no aggressor emitter, whose trigger shows them)",
        f"histogram    pass     peak at {COARSE_AT} in off, mseq, masked (keyed not in this "
        f"build)",
        "calibration  skipped  no fine TDC in this build",
        "link         pass     no link errors, board or host"]
