"""Captures for the tests of the exports and imports (tests/host/test_formats_*.py), written with
:class:`~fliss.host.fileformat.CaptureWriter`, and a TCSPC histogram of two echoes worked out
from the physics for the imports' analysis."""

import math

import numpy as np

from fliss.hdl.registers import defaults
from fliss.host.fileformat import CaptureWriter, read_capture
from fliss.host.stream import EventBatch, HistogramFrame
from fliss.protocol.events import EVENT_DTYPE

import imager_frames as scene


CLOCK_HZ = 80_000_000
LSB_S = 50e-12
PERIOD = 80                              # cycles: 1 µs, 1 MHz
#: The laser cycle of the first event: the 32-bit ``pulse`` wraps during the capture.
FIRST_CYCLE = (1 << 32) - 200_000


def identity():
    return scene.identity()


def raw_capture(path, n=5000, *, seed=3, configuration=None, attrs=None):
    """A raw capture of ``n`` events at laser cycles from :data:`FIRST_CYCLE` on (so that
    ``pulse`` wraps), every address 0 … 63, every TDC code, some collisions; returns
    ``(capture, cycles)`` with the laser cycles unwrapped."""
    rng = np.random.default_rng(seed)
    gaps = rng.geometric(1 / 150, n) - 1                    # several events in one cycle, too
    if n:
        gaps[n // 2] = 3 * 1023 * 1024 + 5                  # a gap of more than 1023 wraps
    cycles = FIRST_CYCLE + np.cumsum(gaps)
    events = np.zeros(n, dtype=EVENT_DTYPE)
    events["pulse"] = cycles & 0xFFFFFFFF
    events["timestamp"] = rng.integers(0, 8192, n)
    events["timestamp"][:2] = (0, 8191)[:n]
    events["address"] = np.arange(n) % 64
    events["collision"] = rng.random(n) < 0.1
    registers = defaults(CLOCK_HZ)
    registers.update(configuration or {})
    with CaptureWriter(str(path), mode="raw", identity=identity(), configuration=registers,
                       attrs=dict({"capture_s": 0.25}, **(attrs or {}))) as writer:
        for start in range(0, max(n, 1), 1000):
            writer.add_events(EventBatch(events[start:start + 1000], 1000.0 + start))
    return read_capture(path), cycles


def histogram_capture(path, rows, *, shift=1, incomplete=(), first_frame=10,
                      configuration=None):
    """A histogram capture of the rows ``rows`` (``(N, 8192 >> shift)``), rows ``incomplete``
    marked so."""
    registers = defaults(CLOCK_HZ)
    registers.update(bin_shift=shift, **(configuration or {}))
    with CaptureWriter(str(path), mode="histogram", identity=identity(),
                       configuration=registers) as writer:
        for i, row in enumerate(rows):
            complete = i not in incomplete
            writer.add_histogram(HistogramFrame(first_frame + i, shift,
                                                np.asarray(row, dtype=np.uint32), complete,
                                                0 if complete else 3, 100.0 + i))
    return read_capture(path)


def image_capture(path, frames=3):
    """An image capture of the synthetic line scene (8 pixels from address 8)."""
    with CaptureWriter(str(path), mode="image", identity=identity(),
                       configuration=scene.configuration()) as writer:
        for frame in scene.histogram_frames(frames):
            writer.add_frame(frame)
    return read_capture(path)


def depth_capture(path):
    with CaptureWriter(str(path), mode="depth", identity=identity(),
                       configuration=scene.configuration()) as writer:
        for frame in scene.depth_frames(np.tile(scene.TRUTH_M, (2, 1))):
            writer.add_frame(frame)
    return read_capture(path)


#: Two echoes in 50 ps codes: the victim's at 26.7 ns (4 m), an aggressor's at 150 ns, half
#: as tall, Gaussian of the paper's 2.1 ns FWHM, over a flat background.
VICTIM_S, AGGRESSOR_S = 26.7e-9, 150e-9


def two_echoes(shift=0, *, seed=5, victim=4000.0, aggressor=2000.0, background=2.0):
    """Counts per bin of ``2**shift`` codes: Poisson draws around the two echoes."""
    sigma = 2.1e-9 / (2 * math.sqrt(2 * math.log(2)))
    bin_s = LSB_S * (1 << shift)
    edges = np.arange(((1 << 13) >> shift) + 1) * bin_s
    cdf = np.vectorize(lambda t, mu: 0.5 * (1 + math.erf((t - mu) / (sigma * math.sqrt(2)))))
    means = background * (1 << shift) + victim * np.diff(cdf(edges, VICTIM_S)) \
        + aggressor * np.diff(cdf(edges, AGGRESSOR_S))
    return np.random.default_rng(seed).poisson(means).astype(np.uint32)
