"""The sensor geometry's flags: values with units, a field of view turned into a focal length by
the pinhole law worked out here, a recorded geometry overridden flag by flag, and bad values
refused in one line naming the flag."""

import argparse
import math

import pytest

from fliss.host.errors import UserError
from fliss.host.pointcloud.options import add_geometry_options, geometry_attribute, geometry_of


def _args(*flags):
    parser = argparse.ArgumentParser()
    add_geometry_options(parser)
    return parser.parse_args(list(flags))


def test_defaults_are_the_papers_pixels_and_say_the_lens_is_assumed():
    geometry, note = geometry_of(_args())
    assert (geometry.columns, geometry.focal_m) == (1, 2.5e-3)
    assert geometry.pitch_m == pytest.approx(30e-6)
    assert "lens is not known" in note and "2.5 mm" in note


def test_a_field_of_view_spans_the_long_side():
    # 64 pixels of 20 µm (1.28 mm) seen over 50 degrees: f = 0.64 mm / tan(25 degrees)
    geometry, note = geometry_of(_args("--pitch", "20um", "--fov", "50deg"))
    assert geometry.focal_m == pytest.approx(0.64e-3 / math.tan(math.radians(25)))
    assert note is None
    # A grid 16 wide (4 rows): the long side is its width
    geometry, _ = geometry_of(_args("--pixel-layout", "grid:16", "--fov", "30deg"))
    assert geometry.focal_m == pytest.approx(16 * 30e-6 / 2 / math.tan(math.radians(15)))


def test_flags_override_a_recorded_geometry_one_by_one():
    recorded, _ = geometry_of(_args("--pixel-layout", "grid:8", "--focal-length", "4mm"))
    geometry, note = geometry_of(_args("--pitch", "10um"), geometry_attribute(recorded))
    assert (geometry.columns, geometry.focal_m) == (8, 4e-3)
    assert geometry.pitch_m == pytest.approx(10e-6)
    assert note is None


def test_a_file_of_positions(tmp_path):
    layout = tmp_path / "pixels.csv"
    layout.write_text("# column,row\n0,0\n2.5,1\n")
    geometry, _ = geometry_of(_args("--pixel-layout", str(layout), "--optical-centre", "0,0"))
    assert geometry.positions == ((0.0, 0.0), (2.5, 1.0))
    ray = geometry.rays([1])[0]
    # The pixel 2.5 pitches right and one down of the centre, 2.5 mm behind the lens
    direction = (2.5 * 30e-6, 30e-6, 2.5e-3)
    norm = math.sqrt(sum(c * c for c in direction))
    assert ray == pytest.approx([c / norm for c in direction])


@pytest.mark.parametrize("flags, message", [
    (("--pitch", "30"), "--pitch 30: give a unit"),
    (("--focal-length=-2mm",), "--focal-length -2mm: length must be positive"),
    (("--fov", "180deg"), "--fov 180deg: the field of view must be between"),
    (("--pixel-layout", "grid:0"), "--pixel-layout grid:0: grid:W takes a positive"),
    (("--pixel-layout", "spiral"), "--pixel-layout spiral: not column, grid:W or a file"),
    (("--optical-centre", "3"), "--optical-centre 3: give X,Y in pixels"),
])
def test_bad_values_are_refused_naming_the_flag(flags, message):
    with pytest.raises(UserError) as refusal:
        geometry_of(_args(*flags))
    assert str(refusal.value).startswith(message)
    assert "\n" not in str(refusal.value)


def test_a_layout_file_with_a_bad_line(tmp_path):
    layout = tmp_path / "pixels.csv"
    layout.write_text("0,0\n1;2\n")
    with pytest.raises(UserError, match=r"line 2: give column,row in pixels, not '1;2'"):
        geometry_of(_args("--pixel-layout", str(layout)))


@pytest.mark.parametrize("layout, addresses, shape", [
    ("grid:8", range(64), (8, 8)),
    ("grid:4", range(8, 16), (2, 4)),       # two whole rows, from the start of row 2
    ("grid:4", range(2, 10), None),         # starts mid-row
    ("grid:4", range(0, 6), None),          # ends mid-row
    ("grid:4", [0, 1, 2, 3, 5, 6, 7, 8], None),   # not one by one
    ("column", range(64), None),
])
def test_the_image_a_grids_pixels_fill(layout, addresses, shape):
    geometry, _ = geometry_of(_args("--pixel-layout", layout))
    assert geometry.image_shape(addresses) == shape


def test_pixels_placed_by_a_table_make_no_image(tmp_path):
    layout = tmp_path / "pixels.csv"
    layout.write_text("".join(f"{a % 2},{a // 2}\n" for a in range(4)))
    geometry, _ = geometry_of(_args("--pixel-layout", str(layout)))
    assert geometry.image_shape(range(4)) is None
