"""``fliss analyze FILE``: the peak table and suppression of captures; per-pixel tables of image
and depth captures."""

import json

import numpy as np

from ...analysis.peaks import FALSE_ALARM
from ..analysis import KEEPS, PileupError, analyze
from ..errors import UserError
from ..imager.analysis import capture_table
from ..kinds import article, names, of_capture
from ..roles import COHERENT, SPREAD, check_references, relation, settings_text
from ..imager.report import table_lines, table_record
from ..units import parse_time
from .common import parse_times, read_capture_file


__all__ = ["register", "run_analyze", "victim_hints", "suppression_record"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "analyze", formatter_class=formatter,
        help="peak table and suppression of a capture; per-pixel table of an image or depth "
             "capture",
        description="Sums the complete histograms of a capture (or histograms the events of a "
                    "raw capture) and prints the background and the peaks: time of flight, "
                    "FWHM, height and role: a peak is one that background alone makes in one "
                    "histogram of a thousand at most (exact Poisson statistics). Its role "
                    "(victim, aggressor or unknown) comes from --victim-tof/--aggressor-tof, or "
                    "else from the settings the file records: with the aggressor off every "
                    "peak is the victim's; with FLISS on (the victim's delays differ from the "
                    "aggressor's) a lone peak is the victim's; with FLISS off a histogram "
                    "cannot tell the victim's echo from the aggressor's peak, and the roles "
                    "are unknown. The suppression S = 10 log10(Pv/Pa) (equation 10 of the "
                    "paper) is printed when the victim's peak is known, as a lower bound "
                    "(S >=) when no aggressor peak stands. "
                    "Of an image capture (--readout image) it prints a table per pixel: the "
                    "depth and ToF of the tallest peak of the pixel's summed histogram, its "
                    "height, the background, detected or not; of a depth capture (--readout "
                    "depth) the median over the frames and the detection rate.")
    parser.add_argument("files", nargs="+", metavar="FILE",
                        help="capture files (HDF5), PTU, Photon-HDF5, HT3, PT3 or SPC files")
    parser.add_argument("--victim-tof", metavar="TIME",
                        help="position of the victim's peak (e.g. 26.7ns)")
    parser.add_argument("--aggressor-tof", nargs="*", default=[], metavar="TIME",
                        help="positions of aggressor peaks")
    parser.add_argument("--tolerance", default="1.5ns", metavar="TIME",
                        help="how far a peak may be from a given position")
    parser.add_argument("--per-acquisition", action="store_true",
                        help="also analyse each histogram on its own")
    parser.add_argument("--json", action="store_true",
                        help="print the results as JSON (a list, one object per file)")
    parser.add_argument("--pileup", choices=KEEPS, default=None,
                        help="correct the histogram for pile-up before the analysis, for a TDC "
                             "that keeps the first photon of a laser cycle (Coates' "
                             "correction) or the last (its counterpart; give the SPAD's "
                             "--dead-time: the paper's sensor and the virtual and model "
                             "boards keep the last photon, with a 20 ns dead time by "
                             "default). Needs the histogram's number of laser cycles: a raw "
                             "capture's is its board's pulse count; give --cycles for a "
                             "histogram capture (docs/scene.md, Pile-up)")
    parser.add_argument("--cycles", type=int, default=None, metavar="N",
                        help="with --pileup: the laser cycles (TDC windows) the analysed "
                             "histogram holds (of a histogram capture: all its complete "
                             "histograms together)")
    parser.add_argument("--dead-time", default=None, metavar="TIME",
                        help="with --pileup last (needed there): the SPAD's non-paralysable "
                             "dead time (20ns on the virtual and model boards by default), "
                             "which decides which photon can be the last; 0ns: every photon "
                             "detected")
    parser.set_defaults(run=run_analyze)


def run_analyze(args):
    victim = parse_times([args.victim_tof], "--victim-tof")[0] if args.victim_tof else None
    aggressors = parse_times(args.aggressor_tof, "--aggressor-tof")
    tolerance = parse_times([args.tolerance], "--tolerance")[0]
    try:
        check_references(victim, aggressors, tolerance)
    except ValueError as error:
        raise UserError(str(error)) from None
    records, found = [], []
    captures = [(path, read_capture_file(path)) for path in args.files]
    for path, capture in captures:
        _check_options_apply(args, path, capture, victim, aggressors)
    pileups = {path: _pileup_of(args, path, capture) for path, capture in captures}
    for path, capture in captures:
        if of_capture(capture).imager:
            rows = capture_table(capture)
            if args.json:
                records.append(table_record(capture, rows))
            else:
                print("\n".join(table_lines(capture, rows)))
            continue
        pileup = pileups[path]
        if args.json:
            records.append(_histogram_record(capture, victim, aggressors, tolerance,
                                             args.per_acquisition, pileup))
            continue
        histogram = capture.total_histogram()
        _print_header(path, capture, histogram)
        if histogram.sum() == 0:
            print("  no counts: nothing to analyse")
            continue
        if pileup is not None:
            print(f"  pile-up corrected: {_pileup_text(pileup)}")
        result = _print_analysis(histogram, capture, victim, aggressors, tolerance,
                                 pileup=pileup)
        found.append((path, capture, result))
        if args.per_acquisition and of_capture(capture).framed:
            for index, row in enumerate(capture.histograms):
                print(f"  acquisition {index} (frame {capture.frames[index]}"
                      f"{'' if capture.complete[index] else ', incomplete'}):")
                _print_analysis(row.astype(np.int64), capture, victim, aggressors, tolerance,
                                indent="    ")
    if args.json:
        print(json.dumps(records, indent=1))
    elif victim is None and not aggressors:
        for line in victim_hints(found, tolerance):
            print(line)
    return 0


def _check_options_apply(args, path, capture, victim, aggressors):
    """Refuse (:exc:`UserError`) an option that would be ignored for ``capture``: positions
    for a per-pixel table, --per-acquisition for a capture of no acquisitions, a position
    beyond the capture's histogram."""
    given = [flag for flag, value in (("--victim-tof", victim is not None),
                                      ("--aggressor-tof", bool(aggressors)),
                                      ("--per-acquisition", args.per_acquisition),
                                      ("--pileup", args.pileup is not None)) if value]
    kind = of_capture(capture)
    if kind.imager and args.pileup is not None:
        raise UserError(f"--pileup applies to {names(lambda kind: not kind.imager)} captures; "
                        f"{path} is {article(capture.mode)} capture: its pixels share the "
                        f"sensor's TDC (one photon a cycle among them all), so one pixel's "
                        f"pile-up depends on the others' and a correction pixel by pixel would "
                        f"not hold")
    if kind.imager:
        if given:
            raise UserError(f"{given[0]} applies to {names(lambda kind: not kind.imager)} "
                            f"captures; {path} is {article(capture.mode)} capture, analysed "
                            f"pixel by pixel without it")
        return
    if args.per_acquisition and not kind.framed:
        raise UserError(f"--per-acquisition applies to "
                        f"{names(lambda kind: kind.framed and not kind.imager)} captures; "
                        f"{path} is a {capture.mode} capture, one stream of events with no "
                        f"acquisitions")
    span_s = len(capture.total_histogram()) * capture.bin_s
    if args.tolerance is not None and "tolerance" in getattr(args, "given", ()) and \
            parse_times([args.tolerance], "--tolerance")[0] * 2 >= span_s:
        raise UserError(f"--tolerance {args.tolerance} is as wide as {path}'s histogram "
                        f"(0 to {span_s * 1e9:g} ns): every peak would be at every position")
    for flag, times in (("--victim-tof", [victim] if victim is not None else []),
                        ("--aggressor-tof", aggressors)):
        for time_s in times:
            if not 0 <= time_s < span_s:
                given = (f"{time_s * 1e9:g} ns" if abs(time_s) < 1e-3 else f"{time_s:g} s")
                raise UserError(f"{flag} {given} is outside {path}'s histogram "
                                f"(0 to {span_s * 1e9:g} ns)")


def victim_hints(found, tolerance_s=1.5e-9):
    """Lines naming the victim's peak of captures taken with FLISS off and on, when their
    roles are unknown: of two captures of the same scene, the aggressor's peak stands only with
    FLISS off and what is left of it only with FLISS on, so the one peak at the same time in
    both is the victim's echo (if they saw the same scene: the user knows, the files do not).
    ``found`` is ``[(path, capture, Analysis)]``."""
    def kind(capture):
        return relation(capture.configuration)[0]
    lines = []
    for on_path, on, on_result in found:
        if kind(on) != SPREAD or not on_result.peaks:
            continue
        for off_path, off, off_result in found:
            if kind(off) != COHERENT or off_result.roles.victim is not None:
                continue
            common = [peak for peak in on_result.peaks
                      if any(abs(peak.position_s - other.position_s) <= tolerance_s
                             for other in off_result.peaks)]
            if len(common) != 1:
                continue
            tof = f"{common[0].position_s * 1e9:.3f}"
            lines.append(f"hint: {off_path} ({settings_text(off.configuration)}) and {on_path} "
                         f"({settings_text(on.configuration)}) have one peak at the same time, "
                         f"{tof} ns; if they saw the same scene it is the victim's echo (the "
                         f"aggressor's peak stands only with FLISS off): give --victim-tof "
                         f"{tof}ns")
    return lines


def _print_header(path, capture, histogram):
    complete = int(capture.complete.sum()) if of_capture(capture).framed else None
    settings = settings_text(capture.configuration)
    print(f"{path}: {capture.mode} capture, "
          + (f"{complete} complete histograms of {len(capture.histograms)}"
             if complete is not None else f"{len(capture.events)} events")
          + f", {int(histogram.sum())} counts, bins of {capture.bin_s * 1e12:g} ps, "
          f"ended: {capture.attrs.get('end_reason', '?')}"
          + (f"\n  settings: {settings}" if settings else ""))
    link = capture.counters.get("link", {})
    if link:
        print(f"  link: {link.get('dropped_frames', 0)} corrupt frames, "
              f"{link.get('missing_packets', 0)} missing packets")


def _analysis(histogram, capture, victim, aggressors, tolerance, pileup=None):
    keep, cycles, dead_s = pileup or (None, None, 0.0)
    try:
        return analyze(histogram, capture.bin_s, configuration=capture.configuration,
                       victim_s=victim, aggressors_s=aggressors, tolerance_s=tolerance,
                       shift=capture.shift, pileup=keep, cycles=cycles, dead_time_s=dead_s)
    except PileupError as error:
        raise UserError(f"--pileup {keep}: {capture.path}: {error}") from None


def _pileup_text(pileup):
    keep, cycles, dead_s = pileup
    dead = f", dead time {dead_s * 1e9:g} ns" if keep == "last" else ""
    return (f"{'Coates (first photon)' if keep == 'first' else 'last photon'}{dead}, "
            f"{cycles} laser cycles")


def _pileup_of(args, path, capture):
    """``(keep, cycles, dead_time_s)`` of ``--pileup`` for ``capture``, or None without it; refuses
    (:exc:`UserError`) when the cycle count is not known or the correction cannot apply."""
    if args.pileup is None:
        for flag, value in (("--cycles", args.cycles), ("--dead-time", args.dead_time)):
            if value is not None:
                raise UserError(f"{flag} {value} applies with --pileup only")
        return None
    said = f"--pileup {args.pileup}"
    dead_s = 0.0
    if args.pileup == "last" and args.dead_time is None:
        raise UserError(f"{said} needs the SPAD's --dead-time: it decides which photon can be "
                        f"the last (20ns on the virtual and model boards by default; 0ns if "
                        f"the SPAD detects every photon)")
    if args.dead_time is not None:
        if args.pileup != "last":
            raise UserError(f"--dead-time {args.dead_time} applies with --pileup last: the "
                            f"first photon of a cycle does not depend on it")
        try:
            dead_s = parse_time(args.dead_time, zero=True)
        except ValueError as error:
            raise UserError(f"--dead-time {args.dead_time}: {error}") from None
    if args.per_acquisition:
        raise UserError(f"{said} with --per-acquisition: the laser cycles of each histogram "
                        f"are not known, only of them all (--cycles)")
    if args.cycles is not None:
        if len(args.files) > 1:
            raise UserError(f"--cycles {args.cycles} is one histogram's: give one file")
        if args.cycles < 1:
            raise UserError(f"--cycles must be at least 1, not {args.cycles}")
        return args.pileup, args.cycles, dead_s
    if of_capture(capture).framed:
        raise UserError(f"{said}: the number of laser cycles of {path}'s histograms is not "
                        f"known ({capture.mode} captures do not record it): give --cycles N")
    return args.pileup, _raw_cycles(said, path, capture), dead_s


def _raw_cycles(said, path, capture):
    # A raw capture's cycles: its board's pulse count at the end (it starts again at START),
    # valid when no event was lost on the way
    start, end = capture.counters.get("board_start"), capture.counters.get("board_end")
    if not start or not end or "pulses" not in end:
        raise UserError(f"{said}: {path} does not record its board's pulse count at the end "
                        f"(the capture did not end normally): give --cycles N")
    lost = {name: int(end[name]) - int(start.get(name, 0)) for name in end
            if name.startswith("dropped_") and name != "dropped_stopped"}
    link = capture.counters.get("link", {})
    lost["link"] = int(link.get("missing_packets", 0)) + int(link.get("dropped_frames", 0))
    lost = {name: count for name, count in lost.items() if count > 0}
    if lost:
        raise UserError(f"{said}: {path} lost events on their way "
                        f"({', '.join(f'{name} {count}' for name, count in lost.items())}): "
                        f"the cycles they were kept in would count as empty")
    pulses = capture.events["pulse"].astype(np.int64)
    if len(pulses) != len(np.unique(pulses)):
        raise UserError(f"{said}: {path} has laser cycles with more than one event (one TDC "
                        f"per pixel?): the correction is for a TDC that keeps one photon a "
                        f"cycle")
    return int(end["pulses"])


def suppression_record(result):
    """The suppression of an :class:`~fliss.host.analysis.Analysis` for JSON: its value in dB
    and whether that is the value (``"equal"``) or a lower bound (``"lower"``, as the text's
    ``S >=``); None when it cannot be told."""
    if result.suppression is None:
        return None
    return {"value_db": result.suppression.s_db, "bound": result.suppression.bound}


def _histogram_record(capture, victim, aggressors, tolerance, per_acquisition=False,
                      pileup=None):
    # The analysis of a histogram or raw capture for --json; with --per-acquisition, each
    # histogram's own under "acquisitions", as the text prints them.
    histogram = capture.total_histogram()
    record = {"file": capture.path, "mode": capture.mode, "bin_s": capture.bin_s,
              "counts": int(histogram.sum()), "end_reason": capture.attrs.get("end_reason"),
              "pileup": None if pileup is None else
              {"keep": pileup[0], "cycles": pileup[1],
               "dead_time_s": pileup[2] if pileup[0] == "last" else None},
              "settings": settings_text(capture.configuration) or None,
              "false_alarm": FALSE_ALARM,
              **_analysis_record(histogram, capture, victim, aggressors, tolerance, pileup)}
    if per_acquisition and of_capture(capture).framed:
        record["acquisitions"] = [
            {"index": index, "frame": int(capture.frames[index]),
             "complete": bool(capture.complete[index]),
             **_analysis_record(row.astype(np.int64), capture, victim, aggressors, tolerance)}
            for index, row in enumerate(capture.histograms)]
    return record


def _analysis_record(histogram, capture, victim, aggressors, tolerance, pileup=None):
    # Background, peaks with their roles, suppression and note of one histogram, for --json.
    record = {"background": None, "peaks": [], "suppression": None, "note": None}
    if histogram.sum():
        result = _analysis(histogram, capture, victim, aggressors, tolerance, pileup)
        record["background"] = result.level
        record["peaks"] = [{"tof_s": peak.position_s, "fwhm_s": peak.fwhm_s,
                            "height": peak.height, "role": role}
                           for peak, role in zip(result.peaks, result.roles.roles)]
        record["suppression"] = suppression_record(result)
        record["note"] = result.note
    return record


def _print_analysis(histogram, capture, victim, aggressors, tolerance, indent="  ",
                    pileup=None):
    result = _analysis(histogram, capture, victim, aggressors, tolerance, pileup)
    print(f"{indent}background: {result.level:.4g} counts per bin")
    if not result.peaks:
        print(f"{indent}no peak above the detection threshold (background alone passes it in "
              f"{FALSE_ALARM:g} of histograms)")
        return result
    print(f"{indent}{'peak':>4} {'ToF (ns)':>10} {'FWHM (ns)':>10} {'height (counts/bin)':>20}"
          f"  role")
    for index, (peak, role) in enumerate(zip(result.peaks, result.roles.roles)):
        print(f"{indent}{index + 1:>4} {peak.position_s * 1e9:>10.3f} {peak.fwhm_s * 1e9:>10.3f}"
              f" {peak.height:>20.4g}  {role}")
    print(f"{indent}roles: {result.note}")
    s = result.suppression
    print(f"{indent}suppression S {s.relation} {s.s_db:.2f} dB" if s is not None else
          f"{indent}suppression S: unknown")
    return result
