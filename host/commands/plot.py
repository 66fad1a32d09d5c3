"""``fliss plot FILE``: the histograms of captures, or the depth and intensity of an image or depth
capture, as a PNG."""

import argparse
import os

import numpy as np

from ...hdl.delay.modes import label as mode_label
from ...hdl.registers import VICTIM
from ..errors import UserError
from ..imager.report import plot_imager
from ..paths import check_output_path
from .common import parse_times, read_capture_file


__all__ = ["register", "run_plot", "curve_label"]


def register(subparsers, formatter):
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


def curve_label(path, configuration):
    """The legend of a capture's curve: its file name, and with the registers it was taken with
    (``configuration``), the victim's delay mode (``"FLISS masked Wm=6"``, named by
    :mod:`fliss.hdl.delay.modes`) and the aggressor."""
    label = os.path.basename(path)
    if configuration:
        c = configuration
        victim = {register.field: c.get(register.name) for register in VICTIM.members}
        label += (f" (FLISS {mode_label(victim['mode'], **victim)}, "
                  f"aggressor {'on' if c.get('aggressor') else 'off'})")
    return label


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
    captures = [(path, read_capture_file(path)) for path in args.files]
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
    window = parse_times(args.range, "--range") if args.range else None
    figure, axes = plt.subplots(figsize=(9, 4.5))
    for path, capture in captures:
        histogram = capture.total_histogram()
        times_ns = (np.arange(len(histogram)) + 0.5) * capture.bin_s * 1e9
        axes.step(times_ns, histogram, where="mid", linewidth=0.8,
                  label=curve_label(path, capture.configuration))
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
