"""The sensor's geometry on the command line and in files: ``--pixel-layout``, ``--pitch``,
``--focal-length`` or ``--fov``, ``--optical-centre``; as JSON in a capture's ``geometry``
attribute. A flag given overrides what a file says; what neither gives is the default, the
paper's sensor (:data:`~.geometry.PAPER_SENSOR`), and :func:`geometry_of` says so."""

import json
import math
from pathlib import Path

from ...hdl.event import ADDRESS_BITS
from ..errors import UserError
from ..units import parse_angle, parse_length
from .geometry import PAPER_SENSOR, SensorGeometry


__all__ = ["add_geometry_options", "geometry_of", "geometry_attribute", "recorded_geometry",
           "FLAGS"]

#: The options' flags, by attribute.
FLAGS = {"pixel_layout": "--pixel-layout", "pitch": "--pitch", "focal_length": "--focal-length",
         "fov": "--fov", "optical_centre": "--optical-centre"}


def add_geometry_options(parser):
    """The geometry's flags, in a group of ``parser``; each defaults to None (not given)."""
    group = parser.add_argument_group(
        "sensor geometry", "where each pixel looks, to place depth frames in metres (default: "
        "the paper's sensor, a column of 30um pixels, behind a 2.5mm lens FLISS assumes)")
    group.add_argument("--pixel-layout", metavar="LAYOUT",
                       help="column (one pixel per row), grid:W (W pixels per row), or a CSV "
                            "file of column,row (in pixels) for each pixel address")
    group.add_argument("--pitch", metavar="LENGTH", help="pixel pitch (30um)")
    lens = group.add_mutually_exclusive_group()
    lens.add_argument("--focal-length", metavar="LENGTH", help="the lens's focal length (2.5mm)")
    lens.add_argument("--fov", metavar="ANGLE",
                      help="field of view over the pixels of the array's long side (40deg)")
    group.add_argument("--optical-centre", metavar="X,Y",
                       help="optical centre in pixels, column,row (the middle of the pixels)")


def _layout(text):
    # (columns, positions) of --pixel-layout
    if text == "column":
        return 1, None
    if text.startswith("grid:"):
        try:
            columns = int(text[5:])
        except ValueError:
            columns = 0
        if columns < 1:
            raise UserError(f"--pixel-layout {text}: grid:W takes a positive whole number of "
                            f"pixels per row (grid:8)")
        return columns, None
    path = Path(text)
    if not path.is_file():
        raise UserError(f"--pixel-layout {text}: not column, grid:W or a file of pixel "
                        f"positions")
    positions = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            column, row = (float(part) for part in line.split(","))
        except ValueError:
            raise UserError(f"--pixel-layout {text}, line {number}: give column,row in pixels, "
                            f"not {line.strip()!r}") from None
        if not (math.isfinite(column) and math.isfinite(row)):
            raise UserError(f"--pixel-layout {text}, line {number}: not a finite position")
        positions.append((column, row))
    if not positions:
        raise UserError(f"--pixel-layout {text}: the file gives no pixel position")
    return 1, tuple(positions)


def _centre(text):
    try:
        x, y = (float(part) for part in text.split(","))
    except ValueError:
        raise UserError(f"--optical-centre {text}: give X,Y in pixels (7.5,0)") from None
    if not (math.isfinite(x) and math.isfinite(y)):
        raise UserError(f"--optical-centre {text}: not a finite position")
    return x, y


def _from_json(text, source):
    try:
        values = json.loads(text)
        return SensorGeometry(
            columns=int(values["columns"]), pitch_m=float(values["pitch_m"]),
            focal_m=float(values["focal_m"]),
            centre=None if values.get("centre") is None else tuple(values["centre"]),
            positions=None if values.get("positions") is None else
            tuple(tuple(p) for p in values["positions"]))
    except (ValueError, KeyError, TypeError) as error:
        raise UserError(f"{source}: its sensor geometry cannot be read ({error})") from None


def geometry_of(args, recorded=None, source="the capture"):
    """The geometry of the flags in ``args`` over the one ``recorded`` (a capture's JSON
    attribute, or None) over the default; returns ``(geometry, note)``, ``note`` a line saying
    that the lens is assumed (the default's, given neither by a flag nor by the capture), or
    None."""
    geometry, assumed = _geometry_and_assumed(args, recorded, source)
    note = None
    if "lens" in assumed:
        where = "the capture records none" if recorded is None else "the capture assumed it"
        note = (f"the lens is not known ({where}, and no --focal-length or --fov is given): "
                f"the points assume a {geometry.focal_m * 1e3:g} mm lens; their ranges are "
                f"measured, their directions are not")
    return geometry, note


def recorded_geometry(args):
    """The JSON a capture records of the geometry of the flags in ``args`` over the default,
    with the settings no flag gave listed as ``assumed``."""
    geometry, assumed = _geometry_and_assumed(args, None, "")
    return geometry_attribute(geometry, assumed)


def _given(args, *names):
    return any(getattr(args, name, None) is not None for name in names)


def _geometry_and_assumed(args, recorded, source):
    # The geometry, and the names of its settings ("layout", "pitch", "lens", "centre") that
    # neither a flag nor the recording gave (the recording's own assumptions carried on)
    if recorded is None:
        base, assumed = PAPER_SENSOR, {"layout", "pitch", "lens", "centre"}
    else:
        base = _from_json(recorded, source)
        try:
            assumed = set(json.loads(recorded).get("assumed", ()))
        except (ValueError, AttributeError):
            assumed = set()
    for name, flags in (("layout", ("pixel_layout",)), ("pitch", ("pitch",)),
                        ("lens", ("focal_length", "fov")), ("centre", ("optical_centre",))):
        if _given(args, *flags):
            assumed.discard(name)
    options = {"columns": base.columns, "pitch_m": base.pitch_m, "focal_m": base.focal_m,
               "centre": base.centre, "positions": base.positions}

    def given(name, parse):
        text = getattr(args, name, None)
        if text is None:
            return None
        try:
            return parse(text)
        except ValueError as error:
            raise UserError(f"{FLAGS[name]} {text}: {error}") from None

    layout = given("pixel_layout", _layout)
    if layout is not None:
        options["columns"], options["positions"] = layout
    for name, key, parse in (("pitch", "pitch_m", parse_length),
                             ("focal_length", "focal_m", parse_length),
                             ("optical_centre", "centre", _centre)):
        value = given(name, parse)
        if value is not None:
            options[key] = value
    geometry = SensorGeometry(**options)
    fov = given("fov", parse_angle)
    if fov is not None:
        try:
            geometry = SensorGeometry.from_fov(fov, _long_side(geometry), **{
                k: v for k, v in options.items() if k != "focal_m"})
        except ValueError as error:
            raise UserError(f"--fov {args.fov}: {error}") from None
    return geometry, assumed


def _long_side(geometry):
    # Pixels along the long side of the array: of the sensor's 64 addresses, a column's all,
    # a grid's width or height, whichever is longer
    if geometry.positions is not None:
        columns = [c for c, _ in geometry.positions]
        rows = [r for _, r in geometry.positions]
        return max(max(columns) - min(columns), max(rows) - min(rows)) + 1
    pixels = 1 << ADDRESS_BITS
    return max(geometry.columns, pixels // geometry.columns)


def geometry_attribute(geometry, assumed=()):
    """The JSON a capture records of ``geometry``; ``assumed``, the names of its settings that
    are defaults nobody gave (``"lens"``, ...)."""
    return json.dumps({**geometry.describe(), "assumed": sorted(assumed)})
