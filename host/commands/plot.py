"""``fliss plot FILE``: the histograms of captures, or the depth and intensity of an image or depth
capture, as a PNG."""

import argparse
import os

import numpy as np

from ..analysis import analyze
from ..errors import UserError
from ..imager.report import image_format, plot_imager
from ..kinds import article, names, of_capture
from ..paths import check_output_path
from ..plotting import legend_below, literal, mark_peaks
from ..roles import check_references, settings_text
from ..units import format_time, parse_time
from .common import parse_times, read_capture_file


__all__ = ["register", "run_plot", "curve_label"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "plot", formatter_class=formatter, help="PNG of the histograms of captures, or the "
                                                "depth and intensity of an image or depth "
                                                "capture",
        description="Plots the summed histogram of each capture file (one curve per file) "
                    "against the time from the TDC start, its victim's and highest aggressor's "
                    "peaks labelled with their ToF as fliss analyze tells them apart (with "
                    "--victim-tof and --aggressor-tof as there; where it cannot, the two "
                    "tallest peaks as of unknown role), and S in the legend (or S unknown). "
                    "Titles and file names are drawn as written (a $ is a dollar). Of one "
                    "image or depth capture it "
                    "draws the depth against the pixel (a line sensor's profile; an image with "
                    "--shape) and the intensity, for all frames together, a grid of frames, "
                    "or an animated GIF of them (--frames).")
    parser.add_argument("files", nargs="+", metavar="FILE",
                        help="capture files (HDF5), PTU, Photon-HDF5, HT3, PT3 or SPC files")
    parser.add_argument("-o", "--output", required=True, metavar="PNG",
                        default=argparse.SUPPRESS,
                        help="image to write (an existing file only with --overwrite)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace the --output file if it exists")
    parser.add_argument("--log", action="store_true", help="logarithmic count axis")
    parser.add_argument("--range", nargs=2, metavar=("START", "END"),
                        help="time range shown, from the TDC start (e.g. 0ns 200ns)")
    parser.add_argument("--title", default=None, help="figure title")
    parser.add_argument("--victim-tof", metavar="TIME",
                        help="position of the victim's peak (e.g. 26.7ns), as for analyze")
    parser.add_argument("--aggressor-tof", nargs="*", default=[], metavar="TIME",
                        help="positions of aggressor peaks, as for analyze")
    parser.add_argument("--frames", choices=["summary", "grid", "animation"],
                        default="summary", help="image and depth captures: all frames "
                        "together, one panel per frame, or a GIF (needs pillow)")
    parser.add_argument("--shape", metavar="ROWSxCOLUMNS", default=None,
                        help="image and depth captures: draw the depth as an image of this "
                             "shape (8x8 for 64 pixels) instead of a profile")
    parser.set_defaults(run=run_plot)


def curve_label(path, configuration):
    """The legend of a capture's curve: its file name, and with the registers it was taken with
    (``configuration``), the victim's delay mode (``"FLISS masked Wm=6"``, named by
    :mod:`fliss.hdl.delay.modes`) and the aggressor (:func:`fliss.host.roles.settings_text`)."""
    settings = settings_text(configuration)
    return os.path.basename(path) + (f" ({settings})" if settings else "")


def run_plot(args):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    check_output_path(args.output, overwrite=args.overwrite)
    suffix = os.path.splitext(args.output)[1].lower().lstrip(".")
    formats = plt.figure().canvas.get_supported_filetypes()
    plt.close("all")
    if suffix and suffix not in formats and not (suffix == "gif" and
                                                  args.frames == "animation"):
        raise UserError(f"--output: cannot write a .{suffix} image; use one of "
                        f"{', '.join('.' + name for name in sorted(formats))}")
    captures = [(path, read_capture_file(path)) for path in args.files]
    imager = [path for path, capture in captures if of_capture(capture).imager]
    if imager and len(captures) > 1:
        mode = captures[args.files.index(imager[0])][1].mode
        raise UserError(f"{imager[0]} is {article(mode)} capture: plot one "
                        f"{names(lambda kind: kind.imager, 'or')} capture at a time")
    if imager:
        plot_imager(captures[0][1], args.output, frames=args.frames, shape=args.shape,
                    title=args.title, quiet=getattr(args, "quiet", 0) > 0)
        return 0
    if args.frames != "summary" or args.shape:
        raise UserError(f"--frames and --shape are for {names(lambda kind: kind.imager)} "
                        f"captures (--readout {names(lambda kind: kind.imager, 'or')})")
    window = _time_range(args.range) if args.range else None
    victim = parse_times([args.victim_tof], "--victim-tof")[0] if args.victim_tof else None
    aggressors = parse_times(args.aggressor_tof, "--aggressor-tof")
    try:
        check_references(victim, aggressors, 1.5e-9)
    except ValueError as error:
        raise UserError(str(error)) from None
    if window:
        _check_window(window, captures)
    figure, axes = plt.subplots(figsize=(9, 5), layout="constrained")
    marks = []
    for path, capture in captures:
        histogram = capture.total_histogram()
        times_ns = (np.arange(len(histogram)) + 0.5) * capture.bin_s * 1e9
        line, = axes.step(times_ns, histogram, where="mid", linewidth=0.8)
        s_text, peaks = _peaks(histogram, capture, victim, aggressors)
        line.set_label(literal(curve_label(path, capture.configuration) + s_text))
        marks += [(*peak, line.get_color()) for peak in peaks]
    axes.set_xlabel("time from TDC start (ns)")
    axes.set_ylabel("counts per bin")
    if args.log:
        axes.set_yscale("log")
    # room above the tallest peak for the stacked labels
    bottom, top = axes.get_ylim()
    axes.set_ylim(bottom, top * 3 ** len(captures) if args.log
                  else top * (1.1 + 0.07 * len(captures)))
    if window:
        axes.set_xlim(window[0] * 1e9, window[1] * 1e9)
    mark_peaks(axes, marks)
    legend_below(figure, *axes.get_legend_handles_labels(), columns=1)
    if args.title:
        axes.set_title(literal(args.title))
    try:
        figure.savefig(args.output, dpi=120, format=image_format(args.output))
    except OSError as error:
        raise UserError(f"cannot write {args.output}: {error.strerror or error}") from None
    finally:
        plt.close(figure)
    if getattr(args, "quiet", 0) <= 0:
        print(f"wrote {args.output}")
    return 0


def _peaks(histogram, capture, victim_s, aggressors_s):
    """The victim's peak and the highest aggressor peak of ``histogram`` as
    :func:`fliss.host.analysis.analyze` tells them apart (``fliss analyze``), or, when it
    cannot, the two tallest peaks labelled as of unknown role: ``(S text for the curve's label,
    [(ToF ns, height, label)])``."""
    if not histogram.sum():
        return "", []
    result = analyze(histogram, capture.bin_s, configuration=capture.configuration,
                     victim_s=victim_s, aggressors_s=aggressors_s, shift=capture.shift)
    level, roles = result.level, result.roles
    if roles.victim is None:
        text = ": roles unknown, S unknown" if result.peaks else ""
        return text, [(peak.position_s * 1e9, level + peak.height,
                       f"peak {peak.position_s * 1e9:.1f} ns (role unknown)")
                      for peak in result.peaks[:2]]
    named = [(roles.victim, "victim", "")]
    if roles.aggressors:
        count = len(roles.aggressors)
        named.append((roles.aggressors[0], "aggressor",
                      f" (highest of {count})" if count > 1 else ""))
    s = result.suppression
    unknown = "unknown" in roles.roles
    text = f": S {s.relation} {s.s_db:.1f} dB" if s is not None else \
        ": S unknown" if unknown else ""               # no aggressor: no S to measure
    return text, [(peak.position_s * 1e9, level + peak.height,
                   f"{name} {peak.position_s * 1e9:.1f} ns{detail}")
                  for peak, name, detail in named]


def _check_window(window, captures):
    """Refuse a --range in which no capture has a bin (beyond the end of every histogram)."""
    ends = [len(capture.total_histogram()) * capture.bin_s for _, capture in captures]
    if ends and window[0] >= max(ends):
        raise UserError(f"--range {format_time(window[0])} {format_time(window[1])}: the "
                        f"histograms end at {format_time(max(ends))}; nothing to draw there")


def _time_range(texts):
    """(start, end) in seconds of ``--range START END``: times from the TDC start, the start
    before the end."""
    said = f"--range {' '.join(texts)}"
    try:
        start, end = (parse_time(text, zero=True) for text in texts)
    except ValueError as error:
        raise UserError(f"{said}: {error}") from None
    if not start < end:
        raise UserError(f"{said}: START ({format_time(start)}) must be before END "
                        f"({format_time(end)})")
    return start, end
