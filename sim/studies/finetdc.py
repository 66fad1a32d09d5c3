"""The fine TDC's figures from its model: non-linearity before and after code-density
calibration, single-shot precision, drift with temperature, and a scene's photons through the
modelled lines.

* :func:`first_sample`: for hits at uniform random times, the time from each hit to the clock
  edge at which the lines first read non-zero, and the code they read;
* :func:`evaluate`: a code-density calibration from one set of hits, judged on another:
  DNL and INL of the raw codes (before) and of the calibrated timestamps (after), the INL of each
  raw code's calibrated time against the truth, and the single-shot RMS error;
* :func:`temperature_drift`: the calibrated TDC's errors after a change of temperature, the
  table left as it was;
* :func:`scene_timestamps`: the timestamps a scene's photons would get from the fine TDC, or from
  the coarse TDC, instead of the paper's 50 ps sensor.

Times are seconds; a hit's time ``tau`` is measured back from the sampling edge.
"""

from dataclasses import replace

import numpy as np

from ...analysis import calibration
from ...hdl.event import TDC_LSB_S, TIMESTAMP_BITS
from ...hdl.finetdc import TABLE_BITS, TAP_S, UNIT_S, lsb_s
from ...hdl.clock import cycle_units
from ..models.finetdc import Line


__all__ = ["READOUTS", "first_sample", "calibrate", "timestamps", "evaluate", "temperature_drift",
           "scene_timestamps", "scene_comparison"]


def first_sample(line, period_s, tau_s, rng):
    """The time before the first non-zero sample and its code, for hits ``tau_s`` (in
    ``(0, period_s]``) before a clock edge: a hit that no tap has seen yet at that edge is seen
    at the next one, a period later."""
    tau = np.asarray(tau_s, dtype=np.float64)
    codes = line.codes(tau, rng)
    late = codes == 0
    tau = np.where(late, tau + period_s, tau)
    codes[late] = line.codes(tau[late], rng)
    return tau, codes


def calibrate(line, clock_hz, hits, rng):
    """A code-density histogram (``line.total_taps + 1`` codes) of ``hits`` uncorrelated hits,
    and the calibration table it gives (in table units)."""
    period = 1 / clock_hz
    _, codes = first_sample(line, period, rng.uniform(0, period, hits), rng)
    counts = np.bincount(codes, minlength=line.total_taps + 1)
    return counts, calibration.table(counts, period, UNIT_S, width=TABLE_BITS)


def timestamps(table, codes, cycles, clock_hz, lsb_select):
    """The gateware's timestamps of hits whose first non-zero sample (of code ``codes``) came
    ``cycles`` whole cycles after the TDC start."""
    ticks = np.asarray(cycles, dtype=np.int64) * cycle_units(clock_hz) - np.asarray(table)[codes]
    return ticks >> (2 - lsb_select)


def _errors(line, table, clock_hz, tau_s, rng, lsb_select):
    # The codes of hits `tau_s` before a clock edge and their calibrated times' errors (times
    # measured less the truth, at the `lsb_select` LSB), the hits 10 cycles after the TDC start
    period = 1 / clock_hz
    tau, codes = first_sample(line, period, tau_s, rng)
    cycles = 10
    measured = timestamps(table, codes, cycles, clock_hz, lsb_select) * lsb_s(lsb_select)
    return tau, codes, measured - (cycles * period - tau)


def _per_code(codes, error, length):
    # Each code's mean error (0 where no hit)
    return np.bincount(codes, error, minlength=length) / np.maximum(
        np.bincount(codes, minlength=length), 1)


def evaluate(line=None, clock_hz=80e6, *, calibration_hits=1 << 22, test_hits=10 ** 6,
             lsb_select=2, nominal_code_s=TAP_S, seed=0):
    """Calibrate the model ``line`` (by default :class:`Line`'s defaults) and judge it on
    ``test_hits`` other hits.

    Returns a dict: ``mean_code_s`` (a period over the codes it covers), ``weighted_code_s``
    (the mean width of the code a hit falls in: wider than ``mean_code_s`` when the codes are
    uneven, as with taps of 8.4 and 62.5 ps in turn), ``full_share`` (the
    share of hits that had passed every tap of every line at their first sample: non-zero if
    the lines are shorter than a period), ``dnl_before`` and ``inl_before`` (raw codes, in
    codes), ``dnl_after`` and ``inl_after`` (calibrated timestamps at 50 ps, in LSBs),
    ``code_inl_before_s`` and ``code_inl_after_s`` (each raw code's mean error, with the table
    at reset, every code ``nominal_code_s`` wide, or calibrated, against the truth, offset
    removed), ``rms_before_s`` and ``rms_after_s`` (single-shot error at the ``lsb_select``
    LSB, offset removed), ``counts`` and ``table``.
    """
    line = Line() if line is None else line
    rng = np.random.default_rng(seed)
    period = 1 / clock_hz
    counts, table = calibrate(line, clock_hz, calibration_hits, rng)
    tau, codes, after = _errors(line, table, clock_hz, rng.uniform(0, period, test_hits), rng,
                                lsb_select)
    before = (0.5 - codes) * nominal_code_s + tau       # the reset table's times, less the truth
    result = {"counts": counts, "table": table,
              "mean_code_s": period / np.count_nonzero(counts),
              "weighted_code_s": period * float((counts.astype(np.float64) ** 2).sum()) /
              float(counts.sum()) ** 2,
              "full_share": counts[line.total_taps] / counts.sum()}
    for name, error in (("before", before), ("after", after)):
        error = error - error.mean()
        result[f"rms_{name}_s"] = float(np.sqrt(np.mean(error ** 2)))
        result[f"code_inl_{name}_s"] = _per_code(codes, error, len(counts))[counts > 0]
    result["dnl_before"] = calibration.dnl(counts)
    result["inl_before"] = calibration.inl(counts)
    # After: the calibrated timestamps of uniform hits at 50 ps, over whole codes of one period
    at_50 = timestamps(table, codes, 10, clock_hz, 0)
    output = np.bincount(at_50 - at_50.min())
    inner = output[1:-1]    # the two edge codes are cut by the period
    result["dnl_after"] = calibration.dnl(inner)
    result["inl_after"] = calibration.inl(inner)
    return result


def temperature_drift(line=None, clock_hz=80e6, *, coefficient_per_k, dts_k,
                      calibration_hits=1 << 22, test_hits=10 ** 6, lsb_select=2, seed=0):
    """The calibrated TDC after a change of temperature, with the table computed before it.

    The model ``line`` is calibrated as it is; then every delay of the chip (taps, and the input
    in front of them) is multiplied by ``1 + coefficient_per_k * dt`` for each ``dt`` of
    ``dts_k`` (kelvin), and the same test hits go through it. The errors are against the truth
    less the mean error before the change (the offset that a range calibration takes off).

    Returns a list of dicts, one per ``dt``: ``dt_k``, ``shift_s`` (the mean error: a range
    offset, ``c / 2`` of it in distance), ``worst_s`` (the largest mean error of a raw code),
    ``rms_s`` (single-shot, at the ``lsb_select`` LSB) and ``rms_centred_s`` (the same with the
    shift taken off, as a new range calibration would).
    """
    line = Line() if line is None else line
    rng = np.random.default_rng(seed)
    period = 1 / clock_hz
    counts, table = calibrate(line, clock_hz, calibration_hits, rng)
    hits = rng.uniform(0, period, test_hits)
    state = rng.bit_generator.state
    _, _, error = _errors(line, table, clock_hz, hits, rng, lsb_select)
    offset = error.mean()
    rows = []
    for dt in dts_k:
        warm = replace(line, scale=line.scale * (1 + coefficient_per_k * dt))
        rng.bit_generator.state = state     # the same metastable draws as before the change
        _, codes, error = _errors(warm, table, clock_hz, hits, rng, lsb_select)
        error = error - offset
        per_code = _per_code(codes, error, len(counts))[
            np.bincount(codes, minlength=len(counts)) > 0]
        rows.append({"dt_k": dt, "shift_s": float(error.mean()),
                     "worst_s": float(np.abs(per_code).max()),
                     "rms_s": float(np.sqrt(np.mean(error ** 2))),
                     "rms_centred_s": float(error.std())})
    return rows


def scene_timestamps(events, line, table, clock_hz, *, lsb_select=0, rng):
    """The timestamps the scene's photons (``events``, 50 ps codes from the TDC start at a clock
    edge) get from the fine TDC (at ``lsb_select``; -1 where it overflows, an event the filter
    drops) and from the coarse TDC (whole cycles), as ``(fine, coarse)``: each photon's time is its code plus a uniform fraction of it (the scene's
    pulses are much wider than 50 ps), then it goes through the line."""
    period = 1 / clock_hz
    t = (np.asarray(events["timestamp"], dtype=np.float64) + rng.random(len(events))) * TDC_LSB_S
    after = np.floor(t / period).astype(np.int64) + 1     # the first edge after the photon
    tau, codes = first_sample(line, period, after * period - t, rng)
    cycles = after + np.rint((tau - (after * period - t)) / period).astype(np.int64)
    fine = timestamps(table, codes, cycles, clock_hz, lsb_select)
    fine[(fine < 0) | (fine >> TIMESTAMP_BITS != 0)] = -1
    return fine, cycles


#: The scene comparison's readouts: name -> (TDC, fine LSB select or None).
READOUTS = {"sensor 50 ps": ("sensor", None), "fine 50 ps": ("fine", 0),
            "fine 12.5 ps": ("fine", 2), "coarse 12.5 ns": ("coarse", None)}


def scene_comparison(*, line=None, clock_hz=80e6, t_int_s=20e-3, seed=0):
    """A target at 4 m and an aggressor 75 ns later, FLISS off (both at the same fixed period)
    and on (the victim's mseq delays, the aggressor at its mean period), each read by the
    paper's sensor, the fine TDC and the coarse TDC.

    Returns a list of dicts: ``fliss`` (``"off"`` or ``"on"``), ``readout`` (a key of
    :data:`READOUTS`), ``tof_s`` and ``fwhm_s`` of the strongest peak (NaN if none; the fine
    TDC's with the line's fixed input delay taken off, as a range calibration would),
    ``truth_tof_s``, ``truth_fwhm_s``, ``peaks`` (how many).
    """
    from ...analysis.peaks import find_peaks
    from ..models.scheduler import Settings
    from ..scene.acquisition import acquire
    from ..scene.description import Aggressor, Scene

    line = Line() if line is None else line
    rng = np.random.default_rng(seed)
    _, table = calibrate(line, clock_hz, 1 << 22, rng)
    rows = []
    for fliss, victim, aggressor_period in (("off", Settings(period=80), 80),
                                            ("on", Settings(mode="mseq", length=6, period=80),
                                             80 + 32)):
        scene = Scene(victim=victim, clock_hz=clock_hz,
                      aggressors=(Aggressor(period_cycles=aggressor_period),))
        events = acquire(scene, t_int_s, 1, seed=seed, keep_events=True).events[0]
        fine_codes = {}
        for readout, (kind, select) in READOUTS.items():
            if kind == "sensor":
                stamps, bin_s, offset = events["timestamp"], TDC_LSB_S, 0.0
            elif kind == "fine":
                if select not in fine_codes:
                    fine_codes[select] = scene_timestamps(events, line, table, clock_hz,
                                                          lsb_select=select, rng=rng)[0]
                stamps, bin_s = fine_codes[select], lsb_s(select)
                offset = float(line.thresholds_s[0])
            else:
                stamps = scene_timestamps(events, line, table, clock_hz, rng=rng)[1]
                bin_s, offset = 1 / clock_hz, 0.0
            stamps = np.asarray(stamps, dtype=np.int64)
            histogram = np.bincount(stamps[stamps >= 0],
                                    minlength=int(round(409.6e-9 / bin_s)))
            peaks = find_peaks(histogram, bin_s=bin_s, sigma_bins=max(250e-12 / bin_s, 0.05))
            best = peaks[0] if peaks else None
            rows.append({"fliss": fliss, "readout": readout,
                         "tof_s": best.position_s - offset if best else float("nan"),
                         "fwhm_s": best.fwhm_s if best else float("nan"),
                         "truth_tof_s": scene.tof_s,
                         "truth_fwhm_s": float(np.hypot(scene.fwhm_s, scene.jitter_fwhm_s)),
                         "peaks": len(peaks)})
    return rows
