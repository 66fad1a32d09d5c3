"""Physics of the pixel-array scene: each pixel's depth and counts, the column sensor's
last-pixel-wins bias and collision flag, the per-pixel sensor.

Every expectation is worked out here from the physics (Poisson statistics, the non-paralysable
dead-time formula, order statistics of the pixels' detections), not taken from the simulator.
"""

import math

import numpy as np
import pytest

from fliss.sim.models import scheduler
from fliss.sim.scene import (COUNTERS, Aggressor, PixelArray, PixelSimulation, Scene, Simulation,
                             acquire, line_pixels, pixels_named, simulation_for)
from fliss.sim.models.scheduler import Settings


C = 299_792_458.0
LSB_S = 50e-12
CODES = 8192
#: The column's collision window: one period of the 625 MHz TDC time base, in codes.
COLLISION_CODES = 32


def sigma_codes(fwhm_ns=2.1, jitter_fwhm_ns=0.1):
    return math.hypot(fwhm_ns, jitter_fwhm_ns) / (2 * math.sqrt(2 * math.log(2))) / 0.05


def z_score(observed, expected, variance=None):
    return (observed - expected) / np.sqrt(expected if variance is None else variance)


def run(scene, cycles, seed=1, chunk_cycles=1 << 13):
    simulation = simulation_for(scene, seed=seed, chunk_cycles=chunk_cycles)
    chunks = list(simulation.chunks(cycles))
    events = np.concatenate([chunk.events for chunk in chunks])
    return events, simulation


def first_photon(m, sigma):
    """Grid, step and density of the first of Poisson(m) photons of a Gaussian pulse of width
    ``sigma`` (centred on 0), given at least one came: m phi(t) exp(-m Phi(t)) / (1 - exp(-m));
    a pixel's dead time, far longer than the pulse, blocks the others."""
    t = np.linspace(-10 * sigma, 10 * sigma, 8001)
    step = t[1] - t[0]
    phi = np.exp(-t ** 2 / (2 * sigma ** 2)) / (sigma * math.sqrt(2 * math.pi))
    cdf = np.cumsum(phi) * step
    return t, step, m * phi * np.exp(-m * cdf) / (1 - math.exp(-m))


def echo_scene(distances, reflectivity, sensor, **options):
    pixels = PixelArray(distance_m=distances, reflectivity=reflectivity, sensor=sensor)
    settings = dict(detections_per_pulse=0.3, background_hz=0.0, pixels=pixels)
    settings.update(options)
    return Scene(**settings)


def echo_means(distances, reflectivity, detections_per_pulse):
    # A Lambertian target filling the pixel: the echo falls as 1 / z**2 from the 4 m reference
    return detections_per_pulse * np.asarray(reflectivity) * (4.0 / np.asarray(distances)) ** 2


@pytest.mark.parametrize("sensor", ["column", "per_pixel"])
def test_each_pixel_peaks_at_its_own_time_of_flight(sensor):
    pixels = line_pixels(pixels=12, object_pixels=(4, 8), sensor=sensor)
    scene = Scene(detections_per_pulse=0.05, background_hz=0.0, pixels=pixels)
    events, _ = run(scene, 30_000)
    assert len(events) > 5000
    for address in range(12):
        distance = 2.5 if 4 <= address < 8 else 4.0
        stamps = events["timestamp"][events["address"] == address].astype(float)
        assert len(stamps) > 200, address
        # floor() of the arrival time lowers the mean code by half a code
        expected = 2 * distance / C / LSB_S - 0.5
        error = sigma_codes() / math.sqrt(len(stamps))
        assert abs(stamps.mean() - expected) < 5 * error + 0.2, (address, stamps.mean(), expected)


@pytest.mark.parametrize("fed", [False, True])
def test_per_pixel_counts_are_one_minus_exp_of_each_pixels_echo(fed):
    # One TDC per pixel, echo only: the pulse (0.9 ns) is far shorter than the dead time, so a
    # pixel records a pulse when it got at least one photon: cycles (1 - exp(-m_i)), m_i from
    # its distance and reflectivity. Fed starts (the virtual board's closed loop, one cycle at a
    # time) take the simulator's other path through windows and spans.
    distances = [1.5, 2.0, 3.0, 4.0, 4.0, 6.0, 8.0, 2.5]
    reflectivity = [0.2, 0.5, 0.8, 0.8, 0.1, 1.0, 0.8, 0.0]
    scene = echo_scene(distances, reflectivity, "per_pixel", detections_per_pulse=0.2)
    cycles = 20_000
    if fed:
        simulation = PixelSimulation(scene, seed=4, chunk_cycles=64, external_starts=True)
        simulation.feed(100 + 80 * np.arange(cycles + 1))
        events = np.concatenate([simulation.step(1).events for _ in range(cycles)])
    else:
        events, simulation = run(scene, cycles)
    means = echo_means(distances, reflectivity, 0.2)
    counts = np.bincount(events["address"], minlength=len(distances))
    for address, mean in enumerate(means):
        p = 1 - math.exp(-mean)
        if p == 0:
            assert counts[address] == 0
            continue
        assert abs(z_score(counts[address], cycles * p, cycles * p * (1 - p))) < 5, address
    assert not events["collision"].any()
    # Every photon counted once, per pixel and source
    total = simulation.pixel_counts
    assert np.array_equal(total[:, :, 0], total[:, :, 1:].sum(axis=2))
    assert np.array_equal(total.sum(axis=0), simulation.counts)
    assert np.array_equal(total[:, 0, COUNTERS.index("recorded")], counts)


@pytest.mark.parametrize("chunk_cycles", [1 << 13, 1])
def test_each_pixel_has_its_own_dead_time(chunk_cycles):
    # Period 32 cycles = 400 ns < 409.6 ns: the windows tile time, every pixel sees a stationary
    # Poisson stream of 20 MHz, and its own non-paralysable SPAD (50 ns) detects 1 / (1 + r
    # tau) = half of its photons. A dead time shared by the 16 pixels would detect far fewer;
    # one forgotten from a chunk to the next (here a window) would detect some 6 % more.
    rate_hz, tau_s = 20e6, 50e-9
    pixels = PixelArray(distance_m=np.full(16, 4.0), sensor="per_pixel")
    scene = Scene(victim=Settings(period=32), detections_per_pulse=0.0, background_hz=rate_hz,
                  dead_time_s=tau_s, pixels=pixels)
    _, simulation = run(scene, 4000, chunk_cycles=chunk_cycles)
    generated, outside, dead, overwritten, recorded = simulation.pixel_counts[:, 1].T
    fraction = (overwritten + recorded).sum() / (generated - outside).sum()
    assert fraction == pytest.approx(1 / (1 + rate_hz * tau_s), rel=0.01)
    each = (overwritten + recorded) / (generated - outside)
    assert np.allclose(each, 1 / (1 + rate_hz * tau_s), rtol=0.04), each


def test_column_last_pixel_to_fire_wins():
    # One TDC for the column, pixels at 1, 3, 5, 7 m (13 ns apart: no collision): pixel i wins
    # a cycle when it fires (p_i = 1 - exp(-m_i)) and no farther pixel fires after it.
    distances = [1.0, 3.0, 5.0, 7.0]
    reflectivity = [0.02, 0.3, 0.8, 1.0]
    scene = echo_scene(distances, reflectivity, "column", detections_per_pulse=0.4)
    cycles = 40_000
    events, simulation = run(scene, cycles)
    p = 1 - np.exp(-echo_means(distances, reflectivity, 0.4))
    wins = np.array([p[i] * np.prod(1 - p[i + 1:]) for i in range(4)])
    counts = np.bincount(events["address"], minlength=4)
    for address in range(4):
        assert abs(z_score(counts[address], cycles * wins[address],
                           cycles * wins[address] * (1 - wins[address]))) < 5, address
    # Each fires as often as alone: nearer pixels lose the cycles a farther one fired in
    fired = simulation.pixel_counts[:, 0, COUNTERS.index("recorded")] + \
        simulation.pixel_counts[:, 0, COUNTERS.index("overwritten")]
    assert np.all(np.abs(z_score(fired, cycles * p, cycles * p * (1 - p))) < 5)
    assert counts[3] == fired[3] and counts[0] < fired[0]
    assert not events["collision"].any()
    # At most one event per laser cycle
    assert len(np.unique(events["pulse"])) == len(events)


@pytest.mark.parametrize("keep", ["last", "first"])
def test_column_collision_of_two_pixels_at_one_distance(keep):
    # Two pixels at 4 m, m photons each per pulse: each pixel's first photon of a pulse (its
    # dead time blocks the rest) has the density m phi(t) exp(-m Phi(t)) / (1 - exp(-m)). When
    # both fire, the later one wins (the earlier, keeping the first), and the flag is set when
    # the other fired less than 32 codes before (after): P(|T1 - T2| < 32).
    m = 0.5
    scene = echo_scene([4.0, 4.0], 1.0, "column", detections_per_pulse=m, keep=keep)
    cycles = 40_000
    events, _ = run(scene, cycles)
    t, step, density = first_photon(m, sigma_codes())
    # P(|T1 - T2| < w) for independent T1, T2 of that density
    difference = np.convolve(density, density[::-1]) * step
    lags = (np.arange(len(difference)) - (len(t) - 1)) * step
    near = difference[np.abs(lags) < COLLISION_CODES].sum() * step
    p = 1 - math.exp(-m)
    expected = cycles * p * p * near
    assert abs(z_score(int(events["collision"].sum()), expected,
                       expected * (1 - p * p * near))) < 5
    assert abs(z_score(len(events), cycles * (1 - (1 - p) ** 2))) < 5


@pytest.mark.parametrize("pixels", [2, 60])
def test_column_collision_fraction_under_background(pixels):
    # Background only, no dead time, rate r per pixel in a window of W codes: the last photon
    # of the column comes at t with density R exp(-R (W - t)), R = P r, and collides when one
    # of another pixel (rate (P - 1) r) fell in [t - w, t): probability 1 - exp(-(P-1) r
    # min(w, t)).
    rate_hz = 2e6 * 60 / pixels
    array = PixelArray(distance_m=np.full(pixels, 4.0), sensor="column")
    scene = Scene(detections_per_pulse=0.0, background_hz=rate_hz, dead_time_s=0.0,
                  pixels=array)
    cycles = 20_000
    events, _ = run(scene, cycles)
    r = rate_hz * LSB_S
    total, others = pixels * r, (pixels - 1) * r
    t = np.linspace(0.0, CODES, 200_001)
    integrand = total * np.exp(-total * (CODES - t)) * \
        (1 - np.exp(-others * np.minimum(COLLISION_CODES, t)))
    p_collision = float(np.sum((integrand[1:] + integrand[:-1]) / 2) * (t[1] - t[0]))
    p_event = 1 - math.exp(-total * CODES)
    assert abs(z_score(len(events), cycles * p_event, cycles * p_event * (1 - p_event) + 1)) < 5
    collided = int(events["collision"].sum())
    expected = cycles * p_collision
    assert abs(z_score(collided, expected, expected * (1 - p_collision))) < 5
    assert collided > 100


def test_flash_aggressor_lights_every_pixel_and_per_pixel_sensor_never_collides():
    # A flash aggressor 75 ns after the victim: every pixel sees it 75 ns after its own echo.
    pixels = line_pixels(pixels=8, object_pixels=(2, 5), sensor="per_pixel")
    aggressor = Aggressor(period_cycles=80, offset_s=75e-9, detections_per_pulse=0.3)
    scene = Scene(detections_per_pulse=0.0, background_hz=0.0, pixels=pixels,
                  aggressors=(aggressor,))
    cycles = 10_000
    events, simulation = run(scene, cycles)
    p = 1 - math.exp(-0.3)
    # The dead time keeps each pixel's first photon of a pulse: earlier than the pulse's centre
    t, step, density = first_photon(0.3, sigma_codes())
    first = float(np.sum(t * density) * step)
    for address in range(8):
        stamps = events["timestamp"][events["address"] == address].astype(float)
        distance = 2.5 if 2 <= address < 5 else 4.0
        assert abs(z_score(len(stamps), cycles * p, cycles * p * (1 - p))) < 5
        expected = (75e-9 + 2 * distance / C) / LSB_S - 0.5 + first
        assert abs(stamps.mean() - expected) < 5 * sigma_codes() / math.sqrt(len(stamps)) + 0.2
    assert not events["collision"].any()
    # Several events per laser cycle: one per pixel that fired, in address order
    per_cycle = np.bincount(events["pulse"].astype(np.int64))
    assert per_cycle.max() > 3
    order = events["pulse"].astype(np.int64) * 64 + events["address"]
    assert np.all(np.diff(order) > 0)
    # The same on the column: one event per cycle, often with the collision flag (the 5 wall
    # pixels fire within a pulse width of each other; the law is tested above on two pixels)
    column, _ = run(scene.replace(pixels=pixels.replace(sensor="column")), cycles)
    assert len(np.unique(column["pulse"])) == len(column)
    assert column["collision"].mean() > 0.25


def test_single_pixel_scene_is_unchanged():
    # Without pixels the single-pixel simulation runs, bit for bit the same events.
    scene = Scene(aggressors=(Aggressor(period_cycles=80),))
    assert type(simulation_for(scene)) is Simulation
    a = acquire(scene, 1e-3, 2, seed=3, keep_events=True)
    simulation = Simulation(scene, seed=3, chunk_cycles=1 << 16)
    pieces = []
    for end in (80_000, 160_000):
        while simulation.next_start_cycle < end:
            pieces.append(simulation.step(until_cycle=end).events)
    events = np.concatenate(pieces)
    assert np.array_equal(np.concatenate(a.events), events)
    assert not events["address"].any() and not events["collision"].any()


def test_acquire_takes_the_pixel_array():
    scene = Scene(pixels=line_pixels(pixels=6, object_pixels=(0, 3)), background_hz=0.0)
    result = acquire(scene, 1e-3, 2, seed=1, keep_events=True)
    events = np.concatenate(result.events)
    assert set(np.unique(events["address"])) <= set(range(6)) and len(events) > 20
    assert result.histograms.sum() == len(events)


def test_scheduler_starts_and_line_defaults():
    pixels = line_pixels()
    assert len(pixels) == 60 and np.array_equal(pixels.addresses, np.arange(60))
    assert np.count_nonzero(pixels.distance_m == 2.5) == 20
    victim = Settings(mode="masked", mask_width=4, seed=9, period=80)
    simulation = simulation_for(Scene(victim=victim, pixels=pixels), seed=1, chunk_cycles=500)
    starts = np.concatenate([chunk.start_cycles for chunk in simulation.chunks(2000)])
    from fliss.sim.models import delay as delay_model
    delays = delay_model.delays("masked", 2000, mask_width=4, seed=9)
    assert np.array_equal(starts, scheduler.fire_cycles(delays, 80) + scheduler.LATENCY)


@pytest.mark.parametrize("options, message", [
    (dict(distance_m=np.zeros((2, 2))), "A pixel array has 1 to 64 pixels: give one distance per "
                                        "pixel, not an array of shape (2, 2)"),
    (dict(distance_m=np.full(65, 4.0)), "A pixel array has 1 to 64 pixels: give one distance per "
                                        "pixel, not an array of shape (65,)"),
    (dict(distance_m=[4.0, 0.0]), "Pixel target distances must be positive (metres)"),
    (dict(distance_m=[4.0, 3.0], reflectivity=[1.0]),
     "Pixel reflectivity must be one number or one per pixel (2), not (1,)"),
    (dict(distance_m=[4.0], reflectivity=-1),
     "Pixel reflectivity must be finite and non-negative for every pixel"),
    (dict(distance_m=[4.0], sensor="row"), "Sensor kind must be one of column, per_pixel, not "
                                           "'row'"),
    (dict(distance_m=[4.0, 4.0], first_address=63),
     "First pixel address must be an integer from 0 to 62 for 2 pixels, not 63"),
])
def test_bad_pixel_arrays_are_refused(options, message):
    with pytest.raises(ValueError) as error:
        PixelArray(**options)
    assert str(error.value) == message
    with pytest.raises(ValueError, match=r"^Scene pixels must be a PixelArray or None, not 3$"):
        Scene(pixels=3)
    with pytest.raises(ValueError, match=r"^The object covers pixels from 0 to 60, not \(50, 70\)$"):
        line_pixels(object_pixels=(50, 70))
    with pytest.raises(ValueError, match=r"^Scene must be one of single, line, not 'grid'$"):
        pixels_named("grid")
    with pytest.raises(ValueError, match=r"^Sensor kind must be one of column, per_pixel, not "
                                         r"'row'$"):
        pixels_named("line", sensor="row")
    assert pixels_named("single") is None and len(pixels_named("line", wall_m=5.0)) == 60
