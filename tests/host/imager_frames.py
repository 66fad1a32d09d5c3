"""Synthetic imager data for the host's tests: a line scene (a wall with an object in front of
some pixels), per-pixel histograms drawn from it with Poisson noise, depth frames of it, and a
stand-in for a board's protocol client that sends given frames.

The scene's numbers are worked out here from the physics (time of flight ``2 d / c``, Gaussian
pulse, bins of ``2**shift`` codes of 50 ps), not from the code under test.
"""

import math

import numpy as np

from fliss.hdl.registers import defaults
from fliss.host.client import IdentityInfo
from fliss.host.stream import DepthFrame, HistogramFrame


CLOCK_HZ = 80_000_000
C = 299_792_458.0
LSB_S = 50e-12
#: A line of 8 pixels, addresses 8 … 15: a wall at 4 m, an object at 2.5 m before pixels 11-13.
FIRST = 8
TRUTH_M = np.array([4.0, 4.0, 4.0, 2.5, 2.5, 2.5, 4.0, 4.0])
SHIFT = 3                       # bins of 8 codes, 400 ps: 1024 bins per pixel
SIGMA_S = 2.1e-9 / 2.3548       # the paper's 2.1 ns FWHM pulse


def configuration(**changes):
    registers = defaults(CLOCK_HZ)
    registers.update(pixel_bits=3, first_pixel=FIRST, bin_shift=SHIFT)
    registers.update(changes)
    return registers


def identity():
    return {"protocol": 3, "gateware_version": "9.9", "registers": 33, "clock_hz": CLOCK_HZ,
            "baud": 3_000_000}


def expected_counts(truth_m=TRUTH_M, shift=SHIFT, signal=300.0, background=0.5):
    """Mean counts ``(P, N)`` per frame: a Gaussian echo of ``signal`` photons at each pixel's
    time of flight over ``background`` counts per bin."""
    bin_s = LSB_S * (1 << shift)
    edges = np.arange(((1 << 13) >> shift) + 1) * bin_s
    means = []
    for depth in truth_m:
        tof = 2 * depth / C
        cdf = np.array([0.5 * (1 + math.erf((edge - tof) / (SIGMA_S * math.sqrt(2))))
                        for edge in edges])
        means.append(background + signal * np.diff(cdf))
    return np.array(means)


def histogram_frames(n, *, seed=1, truth_m=TRUTH_M, first=FIRST, shift=SHIFT, start=0):
    """``n`` :class:`HistogramFrame` of the scene, Poisson noise from ``seed``."""
    rng = np.random.default_rng(seed)
    means = expected_counts(truth_m, shift)
    pixel_bits = len(truth_m).bit_length() - 1
    return [HistogramFrame(start + i, shift, rng.poisson(means).astype(np.uint32).ravel(), True,
                           0, 1000.0 + i, pixel_bits, first) for i in range(n)]


def depth_frames(depths_m, *, first=FIRST, shift=SHIFT, start=0):
    """:class:`DepthFrame` items from depths ``(n, P)`` in metres (NaN: not detected), their
    positions in bins from the start of bin 0, as DEPTH packets give them: ToF
    ``position * bin_s``."""
    bin_s = LSB_S * (1 << shift)
    frames = []
    for i, row in enumerate(np.asarray(depths_m, dtype=float)):
        detected = np.isfinite(row)
        position = np.where(detected, 2 * row / C / bin_s, np.nan)
        frames.append(DepthFrame(start + i, first, shift, position,
                                 np.where(detected, 40.0, 0.0), np.full(len(row), 2.0),
                                 detected, 2000.0 + i))
    return frames


class _Counters:
    def as_dict(self):
        return {"frames": 0}


class _Assembler:
    counters = _Counters()

    def flush(self):
        return []


class FakeClient:
    """What :class:`fliss.host.board.Board` and :func:`fliss.host.acquisition.capture` use of a
    :class:`~fliss.host.client.BoardClient`, sending ``frames`` once started."""

    timeout_s = 0.5
    port_name = "fake"
    last_reply = None

    def __init__(self, frames, registers):
        self.frames, self.registers = list(frames), dict(registers)
        self.identity = IdentityInfo(**identity())
        self.sent = 0
        self.running = False
        self.assembler = _Assembler()
        self.written = []

    def identify(self):
        return self.identity

    def read_registers(self, names=None):
        return dict(self.registers) if names is None else \
            {name: self.registers[name] for name in names}

    def write_registers(self, changes, current=None):
        self.written.append(dict(changes))
        self.registers.update(changes)
        return dict(self.registers)

    def write_checked(self, candidate, changes):
        # (the settings already checked, as BoardClient.write_checked takes them)
        changes = list(changes)
        self.written.append({name: candidate[name] for name in changes})
        self.registers.update({name: candidate[name] for name in changes})
        return dict(candidate)

    def status(self):
        return {"running": self.running, "frames": self.sent, "pulses": 0, "events": 0,
                "dropped_fifo": 0, "dropped_overrun": 0, "dropped_histogram": 0}

    def stop(self):
        self.running = False

    def start(self):
        self.running = True

    def drain(self, **kwargs):
        return []

    def reset_counters(self):
        pass

    def settle(self, frames_at_start=None):
        return []

    def take_data(self):
        return []

    def link_counters(self):
        return {"dropped_frames": 0, "missing_packets": 0, "bytes": 0, "packets": 0}

    def stream(self, **kwargs):
        while self.sent < len(self.frames):
            self.sent += 1
            yield self.frames[self.sent - 1]

    def close(self):
        pass
