"""``fliss analyze FILE`` and ``fliss plot FILE``: capture files read back."""

import argparse
import json
import os
import sys

import numpy as np

from . import analysis
from .cli import UserError
from .fileformat import read_capture
from .imager_analysis import capture_table
from .imager_commands import plot_imager, table_lines, table_record
from .paths import check_output_path
from .units import parse_time


__all__ = ["register", "analyze", "run_analyze", "run_plot"]


def _read(path):
    """The capture in ``path``; one warning line (stderr) for what of it could not be read."""
    try:
        capture = read_capture(path)
    except ValueError as error:
        raise UserError(str(error)) from None
    if capture.problems:
        print(f"fliss: warning: {path}: {'; '.join(capture.problems)}", file=sys.stderr)
    return capture


def _times(texts, flag):
    try:
        return [parse_time(text) for text in texts]
    except ValueError as error:
        raise UserError(f"{flag}: {error}") from None


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
    parser.add_argument("files", nargs="+", metavar="FILE", help="capture files (HDF5)")
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

    parser = subparsers.add_parser(
        "plot", formatter_class=formatter, help="PNG of the histograms of captures, or the "
                                                "depth and intensity of an image or depth "
                                                "capture",
        description="Plots the summed histogram of each capture file (one curve per file) "
                    "against the time from the TDC start. Of one image or depth capture it "
                    "draws the depth against the pixel (a line sensor's profile; an image with "
                    "--shape) and the intensity, for all frames together, a grid of frames, "
                    "or an animated GIF of them (--frames).")
    parser.add_argument("files", nargs="+", metavar="FILE", help="capture files (HDF5)")
    parser.add_argument("-o", "--output", required=True, metavar="PNG",
                        default=argparse.SUPPRESS, help="image to write")
    parser.add_argument("--log", action="store_true", help="logarithmic count axis")
    parser.add_argument("--range", nargs=2, metavar=("START", "END"),
                        help="time range shown (e.g. 0ns 200ns)")
    parser.add_argument("--title", default=None, help="figure title")
    parser.add_argument("--frames", choices=["summary", "grid", "animation"],
                        default="summary", help="image and depth captures: all frames "
                        "together, one panel per frame, or a GIF (needs pillow)")
    parser.add_argument("--shape", metavar="ROWSxCOLUMNS", default=None,
                        help="image and depth captures: draw the depth as an image of this "
                             "shape (8x8 for 64 pixels) instead of a profile")
    parser.set_defaults(run=run_plot)


def analyze(histogram, bin_s, *, victim_s=None, aggressors_s=(), tolerance_s=1.5e-9,
            aggressor_on=False, shift=0):
    """Background, peaks and (when it can be told) suppression of one histogram.

    Returns ``(level, peaks, suppression or None, note)``."""
    sigma_bins = max(5.0 / (1 << shift), 1.0)
    level = analysis.background(histogram, sigma_bins=sigma_bins)
    peaks = analysis.find_peaks(histogram, bin_s=bin_s, sigma_bins=sigma_bins, level=level)
    result, note = None, ""
    if victim_s is None and peaks and (aggressor_on or len(peaks) > 1 or aggressors_s):
        victim_s = peaks[0].position_s
        note = "victim = tallest peak"
        if not aggressors_s:
            aggressors_s = [peak.position_s for peak in peaks[1:]]
    if victim_s is not None and peaks and not aggressors_s:
        # Every other peak is an aggressor's: S is against the highest of them (equation 10).
        aggressors_s = [peak.position_s for peak in peaks
                        if abs(peak.position_s - victim_s) > tolerance_s]
    if victim_s is not None and peaks:
        try:
            result = analysis.suppression(histogram, victim_s, aggressors_s, bin_s=bin_s,
                                          sigma_bins=sigma_bins, tolerance_s=tolerance_s)
        except ValueError as error:
            note = str(error)
    return level, peaks, result, note


def run_analyze(args):
    victim = _times([args.victim_tof], "--victim-tof")[0] if args.victim_tof else None
    aggressors = _times(args.aggressor_tof, "--aggressor-tof")
    tolerance = _times([args.tolerance], "--tolerance")[0]
    records = []
    for path in args.files:
        capture = _read(path)
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


def run_plot(args):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    check_output_path(args.output, overwrite=None)
    suffix = os.path.splitext(args.output)[1].lower().lstrip(".")
    formats = plt.figure().canvas.get_supported_filetypes()
    plt.close("all")
    if suffix and suffix not in formats and not (suffix == "gif" and
                                                  args.frames == "animation"):
        raise UserError(f"--output: cannot write a .{suffix} image; use one of "
                        f"{', '.join('.' + name for name in sorted(formats))}")
    captures = [(path, _read(path)) for path in args.files]
    imager = [path for path, capture in captures if capture.mode in ("image", "depth")]
    if imager and len(captures) > 1:
        raise UserError(f"{imager[0]} is an {captures[args.files.index(imager[0])][1].mode} "
                        f"capture: plot one image or depth capture at a time")
    if imager:
        plot_imager(captures[0][1], args.output, frames=args.frames, shape=args.shape,
                    title=args.title, quiet=getattr(args, "quiet", 0) > 0)
        return 0
    if args.frames != "summary" or args.shape:
        raise UserError("--frames and --shape are for image and depth captures (--readout "
                        "image or depth)")
    window = _times(args.range, "--range") if args.range else None
    figure, axes = plt.subplots(figsize=(9, 4.5))
    for path, capture in captures:
        histogram = capture.total_histogram()
        times_ns = (np.arange(len(histogram)) + 0.5) * capture.bin_s * 1e9
        label = os.path.basename(path)
        if capture.configuration:
            c = capture.configuration
            mode = {0: "off", 1: f"mseq L={c.get('length')}",
                    2: f"masked Wm={c.get('mask_width')}"}.get(c.get("delay_mode"), "?")
            label += f" (FLISS {mode}, aggressor {'on' if c.get('aggressor') else 'off'})"
        axes.step(times_ns, histogram, where="mid", linewidth=0.8, label=label)
    axes.set_xlabel("time from TDC start (ns)")
    axes.set_ylabel("counts per bin")
    if args.log:
        axes.set_yscale("log")
    if window:
        axes.set_xlim(window[0] * 1e9, window[1] * 1e9)
    axes.legend(fontsize="small")
    if args.title:
        axes.set_title(args.title)
    figure.tight_layout()
    try:
        figure.savefig(args.output, dpi=120)
    except OSError as error:
        raise UserError(f"cannot write {args.output}: {error.strerror or error}") from None
    finally:
        plt.close(figure)
    if getattr(args, "quiet", 0) <= 0:
        print(f"wrote {args.output}")
    return 0
