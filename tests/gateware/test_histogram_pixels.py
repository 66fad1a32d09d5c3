"""Histogram engine by (pixel, bin): per-pixel frames against the model, both RAM kinds, several
splits of the bank, events at every clock (every other clock for single-port banks), addresses
outside the frame's pixels, splits that do not fit the bank."""

import numpy as np
import pytest

from fliss.hdl.histogram.engine import Histogram
from fliss.sim.models import histogram as model

from histogram_bench import check_against_model, hazard_stimulus, run_histogram, spaced


def pixel_stimulus(rng, cycles, *, shift, pixel_bits, first_pixel, outside=0.15, ram="dual"):
    """Events with the hazards of :func:`hazard_stimulus` (bins), addresses mostly in the
    frame (runs of one pixel, alternating pixels, random ones), some outside it."""
    valid, timestamps = hazard_stimulus(rng, cycles, bins=(1 << 13) >> shift, shift=shift,
                                        gaps=True)
    pixels = 1 << pixel_bits
    addresses = np.empty(cycles, dtype=np.int64)
    position = 0
    while position < cycles:
        n = int(rng.integers(10, 200))
        kind = rng.integers(3)
        if kind == 0:       # one pixel: same flat index back to back
            chunk = np.full(n, first_pixel + rng.integers(pixels))
        elif kind == 1:     # two pixels alternating: same bin, other pixel, one cycle apart
            a, b = first_pixel + rng.integers(pixels, size=2)
            chunk = np.where(np.arange(n) % 2 == 0, a, b)
        else:
            chunk = first_pixel + rng.integers(pixels, size=n)
        addresses[position:position + n] = chunk[:cycles - position]
        position += n
    wrong = rng.random(cycles) < outside   # any other address, below and above the frame
    others = np.setdiff1d(np.arange(64), np.arange(first_pixel, first_pixel + pixels))
    if len(others):
        addresses[wrong] = rng.choice(others, size=int(wrong.sum()))
    if ram == "single":
        # the same events, at least two cycles apart
        stamped = timestamps | (addresses << 13)
        valid, stamped = spaced(rng, valid, stamped, length=cycles)
        timestamps, addresses = stamped & 0x1fff, stamped >> 13
    return valid, timestamps, addresses


SPLITS = [
    # bank_bits, pixel_bits, first_pixel, shift, integration (the readout of a frame, 6
    # cycles a bin, ends before the next frame does)
    (16, 6, 0, 10, 3_300),     # 64 pixels of 8 bins: the whole sensor
    (16, 2, 7, 8, 1_000),      # 4 pixels of 32 bins from address 7
    (16, 0, 37, 7, 800),       # one pixel of 64 bins: the paper's bench
    (14, 3, 56, 9, 900),       # the last 8 addresses (the iCEBreaker's bank)
    (9, 4, 20, 8, 3_300),      # 16 pixels of 32 bins: a 9-bit bank, full
]


@pytest.mark.parametrize("ram", ["dual", "single"])
@pytest.mark.parametrize("bank_bits, pixel_bits, first_pixel, shift, integration", SPLITS)
def test_pixels_match_model(ram, bank_bits, pixel_bits, first_pixel, shift, integration):
    rng = np.random.default_rng(bank_bits * 1000 + pixel_bits * 100 + first_pixel)
    cycles = 4 * integration
    valid, timestamps, addresses = pixel_stimulus(rng, cycles, shift=shift,
                                                  pixel_bits=pixel_bits,
                                                  first_pixel=first_pixel, ram=ram)
    dut = Histogram(bank_bits=min(bank_bits, 13) if ram == "single" else bank_bits, ram=ram)
    if ram == "single":
        bank_bits = dut.bank_bits    # (clearing 2**14 words after reset takes long here)
    frames, result = run_histogram(dut, valid, timestamps, integration=integration,
                                   shift=shift, addresses=addresses, pixel_bits=pixel_bits,
                                   first_pixel=first_pixel)
    check_against_model(frames, result, valid, timestamps, integration=integration,
                        shift=shift, bank_bits=bank_bits, addresses=addresses,
                        pixel_bits=pixel_bits, first_pixel=first_pixel)
    if pixel_bits < 6:
        assert result["dropped_pixel"] > 50
    assert result["overflow"] == 0      # every split here fits its bank
    # the stimulus hit the hazards: same flat index one cycle (two: single-port) apart
    apart = 1 if ram == "dual" else 2
    cycles_in = np.flatnonzero(valid)
    flat = (addresses[valid] << 13) | (timestamps[valid] >> shift)
    assert np.count_nonzero((np.diff(cycles_in) == apart) & (flat[1:] == flat[:-1])) > \
        (100 if ram == "dual" else 40)
    # every pixel of the frame saw events
    image = sum(counts for counts, _ in frames).reshape(1 << pixel_bits, -1)
    assert np.all(image.sum(axis=1) > 0)


@pytest.mark.parametrize("ram", ["dual", "single"])
@pytest.mark.parametrize("bank_bits, pixel_bits, shift", [(8, 2, 6), (4, 6, 12)])
def test_split_that_does_not_fit(ram, bank_bits, pixel_bits, shift):
    # A split too large for the bank (the register file refuses it; the engine is defined
    # anyway): 2**q pixels of 2**b bins, the rest counted in overflow and dropped_pixel.
    rng = np.random.default_rng(bank_bits)
    integration = 1_700
    valid, timestamps, addresses = pixel_stimulus(rng, 3 * integration, shift=shift,
                                                  pixel_bits=pixel_bits, first_pixel=0,
                                                  ram=ram)
    dut = Histogram(bank_bits=bank_bits, ram=ram)
    q, b = model.split(shift, pixel_bits, bank_bits)
    assert q + b == bank_bits and b < 13 - shift
    frames, result = run_histogram(dut, valid, timestamps, integration=integration,
                                   shift=shift, addresses=addresses, pixel_bits=pixel_bits)
    check_against_model(frames, result, valid, timestamps, integration=integration,
                        shift=shift, bank_bits=bank_bits, addresses=addresses,
                        pixel_bits=pixel_bits)
    assert result["overflow"] > 50
    if q < pixel_bits:
        assert result["dropped_pixel"] > 50


def test_model_pixels_by_hand():
    # 4 pixels from address 10, bins of 2**11 codes: 4 bins each
    counts, overflow, outside = model.histogram(
        [0, 2047, 2048, 8191, 100, 6000, 5, 5], [10, 10, 11, 13, 12, 12, 9, 14],
        shift=11, pixel_bits=2, first_pixel=10)
    assert counts.tolist() == [[2, 0, 0, 0], [0, 1, 0, 0], [1, 0, 1, 0], [0, 0, 0, 1]]
    assert overflow == 0 and outside == 2
    assert model.split(11, 2, 16) == (2, 2) and model.bins_read(11, 16, 2) == 16
    # a 6-bit bank with the same split: fits; with 64 pixels: 64 pixels of one bin
    assert model.split(0, 6, 6) == (6, 0) and model.split(3, 2, 6) == (2, 4)
    with pytest.raises(ValueError, match="Pixel bits must be an integer from 0 to 6, not 7"):
        model.check_settings(pixel_bits=7)
    with pytest.raises(ValueError, match="First pixel must be an address from 0 to 63, not 64"):
        model.check_settings(first_pixel=64)


@pytest.mark.parametrize("ram", ["dual", "single"])
def test_one_pixel_build(ram):
    # A build without the per-pixel logic (max_pixel_bits 0, the iCEBreaker's): one pixel,
    # the address first_pixel, the others dropped and counted.
    rng = np.random.default_rng(37)
    integration, shift, first_pixel = 900, 7, 37
    valid, timestamps, addresses = pixel_stimulus(rng, 3 * integration, shift=shift,
                                                  pixel_bits=0, first_pixel=first_pixel,
                                                  outside=0.4, ram=ram)
    dut = Histogram(bank_bits=13, ram=ram, max_pixel_bits=0)
    frames, result = run_histogram(dut, valid, timestamps, integration=integration,
                                   shift=shift, addresses=addresses, first_pixel=first_pixel)
    check_against_model(frames, result, valid, timestamps, integration=integration,
                        shift=shift, bank_bits=13, addresses=addresses, first_pixel=first_pixel)
    assert result["dropped_pixel"] > 100
