"""The board's self-test: a laser trigger looped back to the TDC, and what it must show.

What reaches the TDC (``jumper``):

* ``None``: the fine TDC's internal loopback, with no wire: the laser's output read back at its
  pad (``tdc_input`` 2) for ``same time`` and ``histogram``, the aggressor's (3) for
  ``delays``. A build without it (no fine TDC) skips the checks that need hits;
* ``"laser"``: a jumper wire from the victim's laser output to the photon input;
* ``"aggressor"``: a jumper wire from the aggressor's trigger output to the photon input.

The laser fires every :func:`period_cycles` cycles: one raw event a pulse must fit the link.

The checks (:func:`selftest`), one :class:`Check` each:

``same time``
    Every laser pulse of a raw acquisition gives one hit, all at the same time from the TDC
    start (within :data:`SPREAD_S` of their median with the fine TDC, one code with the coarse
    one): the loopback delay and its RMS jitter.
``delays``
    The victim's delays, seen through the aggressor (its jumper or its pad). With the victim in
    ``grid`` mode, pulse ``k`` fires ``R[k]`` cycles after its slot and its TDC start with it;
    the aggressor, with no delays, the same period and an offset of :data:`AGGRESSOR_OFFSET`
    cycles, fires ``AGGRESSOR_OFFSET`` cycles after the slot, so its hit lands
    ``AGGRESSOR_OFFSET - R[k]`` cycles (plus the loopback's delay) after start ``k``. The raw
    events' pulse index gives ``k``: the delays must be the reference model's sequence from the
    seed, pulse for pulse (the victim's own hits cannot show it: they are timed from a start
    delayed by the same ``R[k]``). Checked in ``mseq`` and ``masked``; ``keyed`` depends on the
    IV in use, which moves on at each start.
``histogram``
    In every delay mode the build has, the board's histogram of the loopback, in bins as wide as
    the spread allowed (at most), has its tallest bin at the loopback delay or next to it, and
    those three bins hold at least :data:`PEAK_SHARE` of its counts: the victim's own pulses
    stay put whatever the delays (not with the aggressor's jumper); ``keyed`` is skipped while
    the board's keyed source has used every IV under its key (it would fire no pulse).
``calibration``
    A code-density histogram of the on-chip oscillator (:func:`fliss.host.calibration.code_counts`)
    hits the codes from the first to the last, all but at most :data:`EMPTY_SHARE` of them (the
    narrowest, where the two lines' taps nearly coincide), with at least :data:`COVERAGE_HITS`
    hits a code on average: the calibration covers every tap (the fine TDC only); and
    :data:`~fliss.host.calibration.TABLE_SAMPLES` entries of the board's table, read back, are
    within :data:`~fliss.host.calibration.TABLE_TOLERANCE_S` of the times these codes give
    them (the table is left as it is).
``link``
    The link's error counters, the board's and the host's, did not move during the test.

A loopback's delay outside 0 to :data:`MAX_DELAY_S` fails ``same time``, and a failure with
hits that are not the trigger's says to check the wire. The verdict
(:attr:`~fliss.host.checklist.SelfTest.verdict`) is ``"pass"`` only when every check ran and
passed; with a skip it is ``"incomplete"``. The board's pace (:mod:`fliss.host.pace`) is
measured first: on a board slower than real time the acquisitions are
:data:`SIMULATION_DURATIONS_S` and the waits fit the pace. The settings changed are put back
at the end. The reference sequence of the delays
(:mod:`fliss.sim.models.delay` ``delays``) is given by the caller (``reference``), as the code
that talks to a real board does not import the simulator.
"""

import math
import time
from typing import Callable, Optional

import numpy as np

from ..hdl.delay.modes import MODES, DelayMode, core_modes
from ..hdl.event import TIMESTAMP_BITS
from ..hdl.protocol import LINK_FIELDS, NakCode
from ..hdl.codes import code_s
from ..hdl.finetdc import HitInput
from ..hdl.registers import AcquisitionMode, TdcSource
from ..protocol.events import link_events_per_s
from .checklist import CHECKS, Check, SelfTest, SelfTestInterrupted, advice
from .calibration import (LEAST_HITS_PER_CODE, TABLE_SAMPLES, Calibration, code_counts,
                          has_fine_tdc, table_check)
from .errors import BoardRefused, SettingsError
from .keyed import USED_UP
from .pace import REAL_TIME, acquire_timeout_s, host_s, measure_pace


__all__ = ["JUMPERS", "NO_LOOPBACK", "PERIOD_CYCLES", "LINK_SHARE", "AGGRESSOR_OFFSET",
           "SEQUENCE_BITS", "SPREAD_S", "PEAK_SHARE", "COVERAGE_HITS", "EMPTY_SHARE",
           "DURATIONS_S", "SIMULATION_DURATIONS_S", "SIMULATION_RAW_PULSES", "MAX_DELAY_S",
           "CHECKS", "Check", "SelfTest", "SelfTestInterrupted", "period_cycles", "selftest"]


#: What a jumper wire can carry to the photon input.
JUMPERS = ("laser", "aggressor")
#: Why the checks that need hits are skipped with no jumper on a build without the internal
#: loopback (and what runs them, by check: :func:`~fliss.host.checklist.advice`).
NO_LOOPBACK = "no jumper, and this build has no internal loopback (the fine TDC's)"
#: ``tdc_input`` of each trigger's pad read back (the internal loopback).
_PAD_INPUTS = {"laser": HitInput.LASER.value, "aggressor": HitInput.AGGRESSOR.value}
#: The laser's least period during the test, in cycles (longer on a link that could not carry
#: one raw event a pulse at that rate: :func:`period_cycles`).
PERIOD_CYCLES = 800
#: Share of the link's capacity in EVENTS frames that the loopback's hits may take (the rest
#: for the commands' replies; the raw FIFO takes the bursts).
LINK_SHARE = 0.8
#: The aggressor's offset after the victim's slot, in cycles (above the longest delay).
AGGRESSOR_OFFSET = 20
#: ``length`` and ``mask_width`` of the delays during the test (delays up to 15 cycles).
SEQUENCE_BITS = 4
#: Largest distance of a fine TDC's loopback hit from the median of them all.
SPREAD_S = 200e-12
#: Share of a histogram's counts that must lie within the spread of the loopback delay.
PEAK_SHARE = 0.9
#: Least hits a code on average for the calibration's coverage to mean something: a code a
#: quarter of the mean wide is then left empty by chance with a probability below 0.2 %
#: (``fliss calibrate``'s least for a table, :data:`~fliss.host.calibration.LEAST_HITS_PER_CODE`).
COVERAGE_HITS = LEAST_HITS_PER_CODE
#: Largest share of the codes from the first hit to the last that may have no hit. The two
#: lines' taps interleave unevenly: where taps of both nearly coincide, a code is a picosecond
#: or less wide and may get no hit by chance (a code of one line alone is some picoseconds wide).
EMPTY_SHARE = 0.05
#: Seconds of each raw acquisition, of each histogram, of the oscillator's codes and of each
#: histogram of them (some 2000 hits a code at 2.4 MHz: far more than :data:`COVERAGE_HITS`).
DURATIONS_S = {"raw": 0.05, "histogram": 0.05, "calibration": 0.2, "calibration_frame": 0.2}
#: On a board slower than real time (a simulation: :mod:`fliss.host.pace`), the board's seconds
#: of each histogram, of the oscillator's codes and of each histogram of them: the least that
#: gives each check its statistics (50 pulses a histogram at the test's period at 80 MHz; some
#: 29 000 hits of the oscillator, 45 a code, above :data:`COVERAGE_HITS`).
SIMULATION_DURATIONS_S = {"histogram": 0.0005, "calibration": 0.012,
                          "calibration_frame": 0.002}
#: Laser pulses a raw acquisition lasts on a board slower than real time (the 15-pulse ``mseq``
#: sequence more than twice).
SIMULATION_RAW_PULSES = 40
#: Longest delay a loopback may have, from the trigger's clock edge to the TDC: a jumper's is
#: some nanoseconds (its output buffer, a wire, an input buffer); a hit later than this, or
#: before its trigger, comes from another output than the one said.
MAX_DELAY_S = 50e-9


def period_cycles(clock_hz, baud):
    """The laser's period during the test at ``clock_hz`` on a link of ``baud``: at least
    :data:`PERIOD_CYCLES`, and long enough that one raw event a pulse takes at most
    :data:`LINK_SHARE` of the link (the raw FIFO would drop the rest)."""
    return max(PERIOD_CYCLES, math.ceil(clock_hz / (LINK_SHARE * link_events_per_s(baud))))


class _Test:
    """The state of one run of :func:`selftest`."""

    def __init__(self, board, jumper, reference, durations_s, pace):
        self.board, self.client = board, board.client
        self.durations_s, self.pace = durations_s, pace
        self.jumper, self.reference = jumper, reference
        self.before = self.client.read_registers()
        self.current = dict(self.before)
        self.changed = set()
        self.fine = has_fine_tdc(self.client, self.before)
        # the internal loopback: with no jumper, on a build with the fine TDC
        self.internal = jumper is None and self.fine
        self.kind = jumper      # the trigger looped back: "laser", "aggressor" or None
        self.period = period_cycles(board.clock_hz, board.identity.baud)
        self.has_aggressor = self.write({"aggressor": 1})
        self.delay_codes = None
        self.same_time_failed = False

    def write(self, changes):
        """Write ``changes``; False if the build refuses a value."""
        try:
            self.current = self.client.write_registers(changes, current=self.current)
        except BoardRefused as error:
            if error.code != NakCode.OUT_OF_RANGE:
                raise
            return False
        self.changed |= set(changes)
        return True

    def restore(self):
        names = sorted(self.changed - {"table_address", "table_data"})
        self.board.stop()
        self.client.write_registers({name: self.before[name] for name in names},
                                    current=self.current)

    @property
    def code_s(self):
        return code_s(self.current, self.board.clock_hz)

    def base(self, kind):
        """Set up the loopback of trigger ``kind`` (``"laser"`` or ``"aggressor"``): no delays,
        one hit a pulse in range, raw events if the build has them; the reason if the build
        does not take it."""
        self.kind = kind
        source = TdcSource.FINE if self.fine else TdcSource.COARSE
        aggressor = self.kind == "aggressor"
        changes = {
            "delay_mode": DelayMode.OFF.value,
            "period": self.period, "grid": int(aggressor), "pulse_width": 1,
            "tdc_source": source.value, "gate_start": 0, "gate_end": (1 << TIMESTAMP_BITS) - 1,
            "collisions": 0, "pixel_bits": 0, "bin_shift": 0,
            "integration": max(1, round(self.durations_s["histogram"] * self.board.clock_hz)),
            "length": SEQUENCE_BITS, "mask_width": SEQUENCE_BITS, "aggressor": int(aggressor),
        }
        if aggressor:
            changes.update(aggressor_period=self.period, aggressor_offset=AGGRESSOR_OFFSET,
                           aggressor_delay_mode=DelayMode.OFF.value, aggressor_width=1)
        if self.fine:
            changes.update(tdc_input=_PAD_INPUTS[kind] if self.internal else HitInput.PIN.value,
                           fine_lsb=0 if aggressor else 2)
        if aggressor and not self.has_aggressor:
            return "no aggressor emitter in this build"
        if self.internal and not self.write({"tdc_input": _PAD_INPUTS[kind]}):
            return f"this build does not read the {self._what()} back (tdc_input " \
                   f"{_PAD_INPUTS[kind]})"
        if not self.write(changes):
            return "this build does not take the loopback's settings"
        self.raw_events = self.write({"acquisition": AcquisitionMode.RAW.value})
        return None

    def raw(self):
        result = self.board.acquire_raw(f"{self.durations_s['raw']}s")
        events = result.events
        _, first = np.unique(events["pulse"], return_index=True)
        return events[np.sort(first)], len(events), result.pulses

    def histogram_counts(self):
        histograms = self.board.acquire(1, timeout_s=acquire_timeout_s(self.board, self.pace))
        return np.asarray(histograms.counts[0], dtype=np.int64)

    # The checks

    def samples(self):
        """The loopback's timestamps, hits and laser pulses, and whether each pulse gave one
        hit: from raw events, or from a histogram in a build without them."""
        if self.raw_events:
            events, hits, pulses = self.raw()
            return events["timestamp"].astype(np.int64), hits, pulses, \
                hits == len(events) and hits >= pulses - 1
        self.write({"acquisition": AcquisitionMode.HISTOGRAM.value})
        counts = self.histogram_counts()
        pulses = self.current["integration"] // self.period
        return np.repeat(np.arange(len(counts)), counts), int(counts.sum()), pulses, \
            abs(int(counts.sum()) - pulses) <= 1

    def same_time(self):
        self.same_time_failed = True
        stamps, hits, pulses, one_each = self.samples()
        if not hits and self.internal:
            return Check("same time", "fail", f"no hits in {pulses} laser pulses from the "
                                              f"{self._what()} read back at its pad")
        if not hits:
            return Check("same time", "fail", f"no hits in {pulses} laser pulses: {self._wire()}")
        median = int(np.median(stamps))
        offset = AGGRESSOR_OFFSET if self.kind == "aggressor" else 0
        lsb = self.code_s
        allowed = 1 if not self.fine else max(1, round(SPREAD_S / lsb))
        far = np.abs(stamps - median) > allowed
        delay_s = median * lsb - offset / self.board.clock_hz
        rms_s = float(np.std(stamps)) * lsb
        if self.fine or rms_s:
            jitter = f"RMS jitter {rms_s * 1e12:.0f} ps"
        else:       # every hit in one code: the coarse TDC cannot see its jitter
            jitter = f"RMS jitter < {_ns(lsb)}, the coarse TDC's bin"
            rms_s = None
        said = f"{hits} hits of {pulses} pulses at {_ns(delay_s)} ({jitter})"
        self.delay_codes, self.allowed = median, allowed
        self.result.delay_s, self.result.jitter_s = delay_s, rms_s
        if not 0 <= delay_s <= MAX_DELAY_S:
            return Check("same time", "fail", f"{said}: a loopback takes 0 to "
                                              f"{_ns(MAX_DELAY_S)}{self._hint()}")
        if not one_each:
            return Check("same time", "fail", f"{said}: not one hit a pulse{self._hint()}")
        if far.any():
            return Check("same time", "fail", f"{said}: {int(far.sum())} hits more than "
                                              f"{_ns(allowed * lsb)} from the others")
        self.same_time_failed = False
        return Check("same time", "pass", said)

    def delays(self):
        if self.kind != "aggressor":
            return Check("delays", "skipped", "the victim's own hits are timed from its own "
                         "delayed start, so its delays do not show"
                         + advice("delays", self.has_aggressor))
        if not self.raw_events:
            return Check("delays", "skipped", "no raw events in this build (the pulse index "
                                              "of each hit is needed)")
        if self.reference is None:
            return Check("delays", "skipped", "no reference model of the delays given")
        checked = []
        # each mode with delays and without a key (its delays depend on an IV the board moves)
        for mode in (row for row in core_modes(keyed=False) if row.size is not None):
            if not self.write({"delay_mode": mode.mode.value, "grid": 1}):
                continue
            events, hits, pulses = self.raw()
            if not hits:
                return Check("delays", "fail", f"no hits in {mode.name}"
                                               f"{self._hint()}")
            pulse = events["pulse"].astype(np.int64)
            reference = self.reference(mode.name, int(pulse.max()) + 1,
                                       length=SEQUENCE_BITS, mask_width=SEQUENCE_BITS,
                                       seed=self.current["seed"])[pulse]
            cycles = events["timestamp"] * self.code_s * self.board.clock_hz
            measured = AGGRESSOR_OFFSET - cycles
            jumper = np.median(measured - reference)
            seen = np.rint(measured - jumper).astype(np.int64)
            wrong = np.flatnonzero(seen != reference)
            if len(wrong):
                k = wrong[0]
                said = (f"in {mode.name}, pulse {pulse[k]} is delayed {seen[k]} "
                        f"cycles, the model's {reference[k]} (the first that differs")
                # Most pulses off, or no clean loopback: hits from elsewhere than the trigger
                if (2 * len(wrong) > len(pulse) or self.same_time_failed) and self._hint():
                    return Check("delays", "fail", f"{said}; {len(wrong)} of {len(pulse)} "
                                 f"differ){self._hint()}")
                return Check("delays", "fail", f"{said})")
            checked.append(f"{len(pulse)} pulses in {mode.name}")
        self.write({"delay_mode": DelayMode.OFF.value})
        if not checked:
            return Check("delays", "skipped", "this build has no delay mode with a sequence")
        return Check("delays", "pass", f"delays as the model's ({', '.join(checked)})")

    def histogram(self):
        if self.kind == "aggressor":
            return Check("histogram", "skipped", "the photon input carries the aggressor's "
                         "trigger, not the victim's laser"
                         + advice("histogram", self.has_aggressor))
        if self.delay_codes is None:
            return Check("histogram", "skipped", "no loopback delay measured")
        lsb = self.code_s
        # Bins as wide as the spread allowed, at most: the peak's bin and its neighbours
        shift = self.allowed.bit_length() - 1
        expected = self.delay_codes >> shift
        checked, skipped = [], {}
        for mode in MODES.values():
            if not self.write({"delay_mode": mode.mode.value, "grid": 0, "bin_shift": shift,
                               "acquisition": AcquisitionMode.HISTOGRAM.value}):
                skipped.setdefault("not in this build", []).append(mode.name)
                continue
            if mode.keyed and self.client.status()["ivs_used_up"]:
                # (it would fire no pulse)
                skipped.setdefault(f"skipped: {USED_UP}", []).append(mode.name)
                continue
            counts = self.histogram_counts()
            peak = int(np.argmax(counts))
            share = counts[max(0, expected - 1):expected + 2].sum() / max(1, counts.sum())
            if abs(peak - expected) > 1 or share < PEAK_SHARE:
                where = (f"the peak is at {_ns((peak << shift) * lsb)}, not at "
                         if abs(peak - expected) > 1 else
                         f"{share:.0%} of the counts (not {PEAK_SHARE:.0%}) are at ")
                return Check("histogram", "fail", f"in {mode.name} {where}"
                             f"{_ns(self.delay_codes * lsb)}, the loopback's{self._hint()}")
            checked.append(mode.name)
        self.write({"delay_mode": DelayMode.OFF.value})
        detail = f"peak at {_ns(self.delay_codes * lsb)} in {', '.join(checked)}"
        for why, modes in skipped.items():
            detail += f" ({', '.join(modes)} {why})"
        return Check("histogram", "pass", detail)

    def calibration(self):
        if not self.fine:
            return Check("calibration", "skipped", "no fine TDC in this build")
        counts = code_counts(self.board, self.durations_s["calibration"],
                             integration_s=self.durations_s["calibration_frame"],
                             timeout_s=self.frame_timeout_s())
        calibration = Calibration(counts, np.zeros(0), self.board.clock_hz)
        self.result.calibration = calibration
        if not counts.sum():
            return Check("calibration", "fail", "no hits from the on-chip oscillator")
        empty = calibration.empty_codes
        said = (f"{int(counts.sum())} hits on codes {calibration.first_code}-"
                f"{calibration.last_code}, mean {calibration.mean_code_s * 1e12:.1f} ps, "
                f"DNL {calibration.dnl_max:.2f}")
        codes = calibration.last_code - calibration.first_code + 1
        if counts.sum() < COVERAGE_HITS * codes:
            return Check("calibration", "fail", f"{said}: too few hits to check the cover "
                         f"(at least {COVERAGE_HITS} a code)")
        if len(empty) > EMPTY_SHARE * codes:
            return Check("calibration", "fail", f"{said}: {len(empty)} codes without a hit "
                                                f"(first {int(empty[0])}), more than "
                                                f"{EMPTY_SHARE:.0%}")
        table = table_check(self.client, counts, self.board.clock_hz)
        if table is not None:
            return Check("calibration", "fail", f"{said}: {table}")
        narrow = f" ({len(empty)} narrow codes without a hit)" if len(empty) else ""
        return Check("calibration", "pass", f"{said}: every tap covered{narrow}; the "
                                            f"board's table agrees at the {TABLE_SAMPLES} of its "
                                            f"{codes} entries read back")

    def frame_timeout_s(self):
        """The wait for each of the oscillator's histograms at this board's pace (None: the
        board's own)."""
        if self.pace >= REAL_TIME:
            return None
        reply_s = max(2.0, self.client.timeout_s)
        return reply_s + host_s(2 * self.durations_s["calibration_frame"] + 0.05, self.pace)

    def _what(self):
        return {"laser": "laser output", "aggressor": "aggressor's trigger"}[self.kind]

    def _wire(self):
        # What to look at when the hits are not the trigger's: the wire
        return f"check the wire: is the {self._what()}, and nothing else, on the photon input?"

    def _hint(self):
        # The wire's hint after a finding ("" on the internal loopback: no wire)
        return "" if self.internal else f"; {self._wire()}"


def _link_errors(board):
    status = board.status()
    link = board.client.link
    return {**{name: status[name] for name in ("uart_framing_errors", "uart_overruns",
                                               *LINK_FIELDS)},
            "host_dropped_frames": link.dropped_frames,
            "host_missing_packets": link.missing_packets}


def _durations(board, pace, durations_s):
    """The durations at ``pace``: :data:`DURATIONS_S` on a real-time board, else
    :data:`SIMULATION_DURATIONS_S` and raw acquisitions of :data:`SIMULATION_RAW_PULSES`;
    ``durations_s`` overrides either."""
    durations = dict(DURATIONS_S)
    if pace < REAL_TIME:
        raw_s = SIMULATION_RAW_PULSES * period_cycles(board.clock_hz, board.identity.baud) \
            / board.clock_hz
        durations.update(SIMULATION_DURATIONS_S, raw=host_s(raw_s, pace))
    return {**durations, **(durations_s or {})}


def selftest(board, *, jumper: Optional[str] = None, reference: Optional[Callable] = None,
             progress=None, durations_s: Optional[dict] = None,
             pace: Optional[float] = None) -> SelfTest:
    """Run the self-test on ``board`` (a :class:`~fliss.host.board.Board`); ``jumper`` says what
    the photon input carries (see the module), ``reference`` is the model's sequence of delays,
    ``reference(mode, count, length=..., mask_width=..., seed=...)``; ``progress``, if given,
    has ``update(done, extra)`` (called after each check, with its name); ``durations_s``
    changes some of :data:`DURATIONS_S`; ``pace``, the board's seconds per second of the host's,
    is measured (:func:`fliss.host.pace.measure_pace`) when not given: a board slower than real
    time (a simulation) gets :data:`SIMULATION_DURATIONS_S` and waits to match.

    Ctrl-C raises :exc:`SelfTestInterrupted` with the checks finished (the settings put back).
    """
    if jumper is not None and jumper not in JUMPERS:
        raise SettingsError(f"jumper must be one of {', '.join(JUMPERS)} or None, "
                            f"not {jumper!r}")
    started = time.monotonic()
    board.stop()
    result = SelfTest(loop="internal" if jumper is None else jumper)
    errors_before = _link_errors(board)
    try:
        result.pace = measure_pace(board) if pace is None else pace
        test = _Test(board, jumper, reference, _durations(board, result.pace, durations_s),
                     result.pace)
    except KeyboardInterrupt:
        raise SelfTestInterrupted(result) from None
    test.result = result
    result.loop = "internal" if test.internal else jumper or "none"
    try:
        _run_checks(test, result, progress)
    except KeyboardInterrupt:
        result.checks.sort(key=lambda check: CHECKS.index(check.name))
        raise SelfTestInterrupted(result) from None
    errors = {name: value - errors_before[name] for name, value in _link_errors(board).items()}
    moved = [f"{name} {value}" for name, value in errors.items() if value]
    result.checks.append(Check("link", "fail" if moved else "pass",
                               ", ".join(moved) if moved else "no link errors, board or host"))
    result.checks.sort(key=lambda check: CHECKS.index(check.name))
    result.elapsed_s = time.monotonic() - started
    return result


def _run_checks(test, result, progress):
    # The loopbacks, each with its checks: a jumper carries one trigger; the internal loopback
    # reads the laser's pad, then the aggressor's for the delays
    if test.internal:
        loops = [("laser", (test.same_time, test.histogram)), ("aggressor", (test.delays,))]
    elif test.jumper is not None:
        loops = [(test.jumper, (test.same_time, test.delays, test.histogram))]
    else:
        loops = []
        runs = {"same time": ": loop the laser output to the photon input (--jumper laser)",
                "histogram": advice("histogram", test.has_aggressor),
                "delays": advice("delays", test.has_aggressor)}
        result.checks += [Check(name, "skipped", NO_LOOPBACK + runs[name])
                          for name in ("same time", "delays", "histogram")]
    try:
        for kind, checks in loops:
            if (why := test.base(kind)) is not None:
                result.checks += [Check(check.__name__.replace("_", " "), "skipped", why)
                                  for check in checks]
                continue
            for check in checks:
                result.checks.append(check())
                _report(progress, result)
        result.checks.append(test.calibration())
        _report(progress, result)
    finally:
        test.restore()


def _report(progress, result):
    if progress is not None:
        progress.update(len(result.checks), result.checks[-1].name)


def _ns(seconds):
    return f"{seconds * 1e9:.3f} ns"
