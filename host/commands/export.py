"""``fliss export CAPTURE --to ptu|photon-hdf5|ply|pcd|las|mcap|mcap-ros2 -o OUT``: a capture
in another program's format; a depth capture as a point cloud (:mod:`.export_points`)."""

import argparse
import os
import time

from ..errors import FormatError, UserError
from ..formats import FORMATS, check_name, export_capture
from ..paths import check_output_path
from ..pointcloud.options import add_geometry_options
from .common import read_capture_file
from .export_points import POINT_FORMATS, refuse_geometry_flags, run_points


__all__ = ["register", "run_export"]


def register(subparsers, formatter):
    parser = subparsers.add_parser(
        "export", formatter_class=formatter,
        help="write a capture as PTU (PicoQuant) or Photon-HDF5, a depth capture as a point "
             "cloud (PLY, PCD, LAS, MCAP)",
        description="Writes a capture in a format other TCSPC programs read. A raw capture "
                    "becomes time-tagged records: the laser cycle as the sync count, the TDC "
                    "code as the micro time, the pixel address as the channel (PTU: T3 "
                    "records; Photon-HDF5: timestamps, nanotimes, detectors). A histogram or "
                    "image capture becomes a PTU file in T3 image mode (one frame per "
                    "histogram, one image pixel per sensor pixel); Photon-HDF5 holds photons "
                    "only. A depth capture becomes a point cloud: one point per detected pixel "
                    "per frame, placed by the sensor's geometry (recorded by fliss capture, or "
                    "given here), in PLY, PCD, LAS or MCAP for Foxglove (docs/point-clouds.md). "
                    "The settings (delay mode, "
                    "L or Wm, seed or IV, PRF; never the key) go into the file's own "
                    "metadata. A recording of another instrument (a PTU, HT3, PT3 or SPC file) "
                    "converts as a raw capture of its photons. Mapping and losses: "
                    "docs/file-format.md.")
    parser.add_argument("capture", metavar="CAPTURE",
                        help="capture file (HDF5), or a PTU, Photon-HDF5, HT3, PT3 or SPC file")
    parser.add_argument("--to", required=True, choices=sorted({*FORMATS, *POINT_FORMATS}),
                        default=argparse.SUPPRESS, help="output format")
    parser.add_argument("-o", "--output", required=True, metavar="OUT",
                        default=argparse.SUPPRESS, help="file to write")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing OUT")
    parser.add_argument("--any-extension", action="store_true",
                        help="write OUT under a name of another ending than the format's "
                             "(.ptu; .hdf5 or .h5; .ply, ...), which is refused otherwise")
    add_geometry_options(parser)
    parser.set_defaults(run=run_export)


def run_export(args):
    check_output_path(args.output, overwrite=args.overwrite)
    if not args.any_extension:
        try:
            check_name(args.output, args.to, flag="-o")
        except FormatError as error:
            raise UserError(str(error)) from None
    if os.path.exists(args.output) and os.path.exists(args.capture) and \
            os.path.samefile(args.output, args.capture):
        raise UserError(f"--output: {args.output} is the capture itself; give another file")
    if args.to in POINT_FORMATS:
        return run_points(args)
    refuse_geometry_flags(args)
    capture = read_capture_file(args.capture)
    start = time.perf_counter()
    try:
        written = export_capture(capture, args.output, args.to)
    except FormatError as error:
        raise UserError(str(error)) from None
    except OSError as error:
        raise UserError(f"cannot write {args.output}: {error.strerror or error}") from None
    if getattr(args, "quiet", 0) <= 0:
        what = "photons" if args.to == "photon-hdf5" else "records"
        print(f"wrote {args.output}: {FORMATS[args.to][0]}, {written} {what}, "
              f"{os.path.getsize(args.output)} bytes, {time.perf_counter() - start:.2f} s")
    return 0
