"""The imager's settings (issue 17): --pixels, --pixel, --first-pixel, the pixel split against
the histogram bank, --readout image|depth, and `fliss config` in units."""

import pytest

from fliss.hdl.registers import defaults
from fliss.host.cli import main
from fliss.host.commands.config import describe as describe_register
from fliss.host.errors import SettingsError
from fliss.host.settings import check_offline, convert, describe

from imager_frames import CLOCK_HZ


def _convert(style="keyword", bank_bits=16, **settings):
    return convert(settings, CLOCK_HZ, defaults(CLOCK_HZ), style=style, bank_bits=bank_bits)


@pytest.mark.parametrize("pixels, bits", [(1, 0), (2, 1), (8, 3), (64, 6), ("0x10", 4)])
def test_pixels_sets_pixel_bits(pixels, bits):
    # Bins wide enough for every split: 64 pixels x 128 bins (bin shift 6) fits 2**13. (The new
    # split sets the depth threshold too: test_a_new_split_sets_the_depth_threshold.)
    changes = _convert(pixels=pixels, bin_shift=6, depth_threshold=9).changes
    assert changes == {"pixel_bits": bits, "bin_shift": 6, "depth_threshold": 9}


def test_a_new_split_sets_the_depth_threshold():
    # 64 pixels of 1024 bins (bin shift 3), 10 ms at 1 MHz: at most 10 000 laser cycles, so a
    # column that fires every cycle gives a pixel b = 10 000 / 65 536 = 0.153 counts per bin,
    # mu = 4 b = 0.610 in a window of the 4-bin filter. Of 1024 / 4 = 256 windows, background
    # may reach the threshold in 1 % of frames: P(X >= k) <= 3.9e-5 for X ~ Poisson(0.610):
    # P(X >= 6) = 4.3e-5, P(X >= 7) = 3.7e-6, so k = 7 counts, a height of 7 - 0.61: 7.
    assert _convert(pixels=64, bin_shift=3).changes == {"pixel_bits": 6, "bin_shift": 3,
                                                         "depth_threshold": 7}
    # At 2 ms, mu = 0.122: P(X >= 3) = 2.8e-4, P(X >= 4) = 8.4e-6, a height of 4 - 0.12: 4.
    assert _convert(pixels=64, bin_shift=3, integration="2ms").changes["depth_threshold"] == 4
    # Set so, it follows the integration time: 2 ms later, 4.
    current = dict(defaults(CLOCK_HZ), pixel_bits=6, bin_shift=3, depth_threshold=7)
    assert convert({"integration": "2ms"}, CLOCK_HZ, current).changes == \
        {"integration": 160_000, "depth_threshold": 4}
    # Given with the split, the threshold is the one given; one set by hand stays until the
    # next split.
    assert _convert(pixels=64, bin_shift=3, depth_threshold=3).changes["depth_threshold"] == 3
    current = dict(current, depth_threshold=5)
    assert convert({"integration": "2ms", "bin_shift": 3}, CLOCK_HZ, current).changes == \
        {"integration": 160_000, "bin_shift": 3}


@pytest.mark.parametrize("pixels, nearest", [(3, "2 or 4"), (60, "64"), (48, "32 or 64"),
                                             (100, "64"), (0, "1"), (-4, "1"), (5, "4")])
def test_pixels_not_a_power_of_two_names_the_nearest(pixels, nearest):
    with pytest.raises(SettingsError) as caught:
        _convert(style="flag", pixels=pixels)
    assert str(caught.value) == (f"--pixels {pixels}: takes a power of two from 1 to 64; the "
                                 f"nearest is {nearest}")


def test_single_pixel_bench():
    assert _convert(pixel=17).changes == {"pixel_bits": 0, "first_pixel": 17}
    settings = describe(_convert(pixel=17).registers, CLOCK_HZ)
    assert settings["pixels"] == 1 and settings["first_pixel"] == 17
    assert list(settings.addresses) == [17] and settings.bins == 8192
    with pytest.raises(SettingsError, match=r"^--pixel 64: takes a pixel address from 0 to 63$"):
        _convert(style="flag", pixel=64)
    with pytest.raises(SettingsError, match="--pixels and --pixel both set pixel_bits"):
        _convert(style="flag", pixels=4, pixel=3)


@pytest.mark.parametrize("bank_bits, pixels, shift, need, most", [
    (16, 64, 0, 3, 8), (16, 64, 2, 3, 32), (16, 16, 0, 1, 8), (14, 64, 3, 5, 16),
    (14, 4, 0, 1, 2)])
def test_a_split_that_does_not_fit_says_what_would(bank_bits, pixels, shift, need, most):
    # pixels x 2**(13 - shift) bins must fit 2**bank_bits: worked out by hand in the table.
    assert pixels * (8192 >> shift) > 1 << bank_bits
    assert pixels * (8192 >> need) <= 1 << bank_bits < pixels * (8192 >> (need - 1))
    with pytest.raises(SettingsError) as caught:
        _convert(style="flag", bank_bits=bank_bits, pixels=pixels, bin_shift=shift)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith(f"--pixels {pixels} with --bin-shift {shift} ")
    assert f"{pixels} pixels need bins of at least {1 << need} codes (--bin-shift {need})" \
        in message
    assert message.endswith(f"at most {most} pixels (--pixels {most})")
    # What it proposes fits.
    _convert(bank_bits=bank_bits, pixels=pixels, bin_shift=need)
    _convert(bank_bits=bank_bits, pixels=most, bin_shift=shift)


def test_the_split_is_checked_against_the_registers_already_set():
    registers = dict(defaults(CLOCK_HZ), pixel_bits=6, bin_shift=3)
    with pytest.raises(SettingsError, match=r"^pixels=64 with bin_shift=2 .*bins of at least 8 codes \(bin_shift=3\)"):
        convert({"bin_shift": 2}, CLOCK_HZ, registers)


def test_first_pixel_beyond_the_sensor():
    with pytest.raises(SettingsError) as caught:
        _convert(style="flag", pixels=8, first_pixel=60, bin_shift=3)
    assert str(caught.value) == ("--first-pixel 60 with 8 pixels reaches address 67, beyond "
                                 "the sensor's last (63): use --first-pixel 56 or lower")


def test_readout_image_and_depth():
    assert _convert(readout="image").changes == {"acquisition": 0}
    assert _convert(readout="depth").changes == {"acquisition": 2}
    assert describe(_convert(readout="depth").registers, CLOCK_HZ)["readout"] == "depth"


def test_the_other_imager_settings():
    changes = _convert(collisions="drop", histogram_format="full", depth_filter=8,
                       depth_threshold=30).changes
    assert changes == {"collisions": 1, "full_readout": 1, "depth_filter": 8,
                       "depth_threshold": 30}


def test_check_offline_needs_no_board():
    check_offline({"pixels": "64", "bin_shift": "3", "integration": "bogus"})   # time: later
    with pytest.raises(SettingsError, match="--pixels 7: takes a power of two"):
        check_offline({"pixels": "7"})
    with pytest.raises(SettingsError, match=r"--pixels 64 with --bin-shift 1 .* \(--bin-shift 3\)"):
        check_offline({"pixels": "64", "bin_shift": "1"})


def test_config_shows_the_split_in_units():
    registers = dict(defaults(CLOCK_HZ), pixel_bits=6, bin_shift=3, first_pixel=0,
                     depth_filter=4, collisions=1, acquisition=2)
    # Bins of 8 codes of 50 ps: 400 ps; 8192 >> 3 = 1024 bins per pixel.
    assert describe_register("bin_shift", 3, registers, CLOCK_HZ) == \
        "bins of 400 ps, 1024 per pixel"
    assert describe_register("pixel_bits", 6, registers, CLOCK_HZ) == "64 pixels per frame"
    assert describe_register("first_pixel", 0, registers, CLOCK_HZ) == "pixels 0 to 63"
    assert describe_register("depth_filter", 4, registers, CLOCK_HZ) == "4 bins, 1.6 ns"
    assert describe_register("collisions", 1, registers, CLOCK_HZ) == "drop (counted)"
    assert describe_register("acquisition", 2, registers, CLOCK_HZ) == "depth"


@pytest.mark.parametrize("argv, message", [
    (["--pixels", "60"], "--pixels 60: takes a power of two from 1 to 64; the nearest is 64"),
    (["--pixels", "64", "--bin-shift", "0"], "64 pixels need bins of at least 8 codes "
                                             "(--bin-shift 3)"),
    (["--pixel", "99"], "--pixel 99: takes a pixel address from 0 to 63"),
])
@pytest.mark.parametrize("command", [["config"], ["capture", "-o", "{d}/x.h5"]])
def test_the_commands_refuse_before_opening_the_port(command, argv, message, tmp_path, capsys):
    # The port does not exist: the refusal comes first, in one line.
    args = [part.format(d=tmp_path) for part in command] + ["--port", str(tmp_path / "none")]
    assert main(args + argv) == 1
    out, err = capsys.readouterr()
    assert out == "" and len(err.splitlines()) == 1
    assert err.startswith("fliss: error: ") and message in err
