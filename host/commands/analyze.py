"""``fliss analyze FILE``: the peak table and suppression of captures; per-pixel tables of image
and depth captures."""

import json

import numpy as np

from ..analysis import analyze
from ..imager.analysis import capture_table
from ..imager.report import table_lines, table_record
from .common import parse_times, read_capture_file


__all__ = ["register", "run_analyze"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "analyze", formatter_class=formatter,
        help="peak table and suppression of a capture; per-pixel table of an image or depth "
             "capture",
        description="Sums the complete histograms of a capture (or histograms the events of a "
                    "raw capture) and prints the background and the peaks: time of flight, "
                    "FWHM and height. The suppression S = 10 log10(Pv/Pa) (equation 10 of the "
                    "paper) is printed when the victim's and the aggressors' peaks can be told "
                    "apart: by --victim-tof/--aggressor-tof, or else, when the capture had the "
                    "aggressor on or shows several peaks, the victim's peak is the tallest. "
                    "Of an image capture (--readout image) it prints a table per pixel: the "
                    "depth and ToF of the tallest peak of the pixel's summed histogram, its "
                    "height, the background, detected or not; of a depth capture (--readout "
                    "depth) the median over the frames and the detection rate.")
    parser.add_argument("files", nargs="+", metavar="FILE",
                        help="capture files (HDF5), PTU or Photon-HDF5 files")
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
    parser.set_defaults(run=run_analyze)


def run_analyze(args):
    victim = parse_times([args.victim_tof], "--victim-tof")[0] if args.victim_tof else None
    aggressors = parse_times(args.aggressor_tof, "--aggressor-tof")
    tolerance = parse_times([args.tolerance], "--tolerance")[0]
    records = []
    for path in args.files:
        capture = read_capture_file(path)
        if capture.mode in ("image", "depth"):
            rows = capture_table(capture)
            if args.json:
                records.append(table_record(capture, rows))
            else:
                print("\n".join(table_lines(capture, rows)))
            continue
        if args.json:
            records.append(_histogram_record(capture, victim, aggressors, tolerance))
            continue
        histogram = capture.total_histogram()
        complete = int(capture.complete.sum()) if capture.mode == "histogram" else None
        print(f"{path}: {capture.mode} capture, "
              + (f"{complete} complete histograms of {len(capture.histograms)}"
                 if complete is not None else f"{len(capture.events)} events")
              + f", {int(histogram.sum())} counts, bins of {capture.bin_s * 1e12:g} ps, "
              f"ended: {capture.attrs.get('end_reason', '?')}")
        link = capture.counters.get("link", {})
        if link:
            print(f"  link: {link.get('dropped_frames', 0)} corrupt frames, "
                  f"{link.get('missing_packets', 0)} missing packets")
        if histogram.sum() == 0:
            print("  no counts: nothing to analyse")
            continue
        aggressor_on = bool(capture.configuration.get("aggressor", 0))
        _print_analysis(histogram, capture, victim, aggressors, tolerance, aggressor_on)
        if args.per_acquisition and capture.mode == "histogram":
            for index, row in enumerate(capture.histograms):
                print(f"  acquisition {index} (frame {capture.frames[index]}"
                      f"{'' if capture.complete[index] else ', incomplete'}):")
                _print_analysis(row.astype(np.int64), capture, victim, aggressors, tolerance,
                                aggressor_on, indent="    ")
    if args.json:
        print(json.dumps(records, indent=1))
    return 0


def _histogram_record(capture, victim, aggressors, tolerance):
    # The analysis of a histogram or raw capture for --json.
    histogram = capture.total_histogram()
    record = {"file": capture.path, "mode": capture.mode, "bin_s": capture.bin_s,
              "counts": int(histogram.sum()), "end_reason": capture.attrs.get("end_reason"),
              "background": None, "peaks": [], "suppression_db": None}
    if histogram.sum():
        level, peaks, result, _ = analyze(
            histogram, capture.bin_s, victim_s=victim, aggressors_s=aggressors,
            tolerance_s=tolerance, aggressor_on=bool(capture.configuration.get("aggressor")),
            shift=capture.shift)
        record["background"] = level
        record["peaks"] = [{"tof_s": peak.position_s, "fwhm_s": peak.fwhm_s,
                            "height": peak.height} for peak in peaks]
        if result is not None:
            record["suppression_db"] = result.s_db
    return record


def _print_analysis(histogram, capture, victim, aggressors, tolerance, aggressor_on,
                    indent="  "):
    level, peaks, result, note = analyze(histogram, capture.bin_s, victim_s=victim,
                                         aggressors_s=aggressors, tolerance_s=tolerance,
                                         aggressor_on=aggressor_on, shift=capture.shift)
    print(f"{indent}background: {level:.4g} counts per bin")
    if not peaks:
        print(f"{indent}no peak above the detection threshold")
        return
    print(f"{indent}{'peak':>4} {'ToF (ns)':>10} {'FWHM (ns)':>10} {'height (counts/bin)':>20}")
    for index, peak in enumerate(peaks):
        role = ""
        if result is not None:
            role = " victim" if peak is result.victim or peak == result.victim else \
                (" aggressor" if peak in result.aggressors else "")
        print(f"{indent}{index + 1:>4} {peak.position_s * 1e9:>10.3f} {peak.fwhm_s * 1e9:>10.3f}"
              f" {peak.height:>20.4g}{role}")
    if result is not None:
        relation = ">=" if result.limited else "="
        detail = " (no aggressor peak above the detection threshold)" if result.limited else ""
        print(f"{indent}suppression S {relation} {result.s_db:.2f} dB{detail}"
              + (f" [{note}]" if note else ""))
    elif note:
        print(f"{indent}suppression: {note}")
