"""The scene simulator's detector, each effect held to its closed form.

Every expectation is worked out here from the physics (Poisson statistics, the dead-time count
rate formulas, the geometric series of afterpulses, exponential and exponentially modified
Gaussian laws, reachability over the pixels' crosstalk links), not taken from the simulator;
tolerances are 5 standard deviations of the counts (or a chi-square 5 sigma above its degrees
of freedom), with fixed seeds.
"""

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from fliss.sim.scene import (COUNTERS, PRESETS, Detector, PixelArray, Scene, simulation_for,
                             time_of_flight)
from fliss.sim.scene.avalanches import Avalanches
from fliss.sim.models.scheduler import Settings


LSB_S = 50e-12
CODES = 8192


def run(scene, cycles, seed=1, chunk_cycles=1 << 14):
    simulation = simulation_for(scene, seed=seed, chunk_cycles=chunk_cycles)
    chunks = list(simulation.chunks(cycles))
    events = np.concatenate([chunk.events for chunk in chunks])
    return events, simulation


def counter(simulation, source, name):
    return int(simulation.counts[simulation.scene.sources.index(source), COUNTERS.index(name)])


def detected(simulation, source):
    """Detections of ``source`` in the TDC windows: recorded or overwritten."""
    return counter(simulation, source, "recorded") + counter(simulation, source, "overwritten")


def phi(x):
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


def within(observed, expected, sigma, sigmas=5.0):
    return abs(observed - expected) <= sigmas * sigma


def chi_square(observed, expected):
    """Chi-square of binned counts and its 5 sigma bound (degrees of freedom: bins - 1)."""
    observed, expected = np.asarray(observed, float), np.asarray(expected, float)
    value = float(((observed - expected) ** 2 / expected).sum())
    dof = len(observed) - 1
    return value, dof + 5.0 * math.sqrt(2.0 * dof)


def test_default_detector_is_the_old_scene():
    # A scene given the default detector (its dead time and jitter) runs as one without
    # (the old runs, which tests/models/test_scene*.py check): same events, same counters.
    old = Scene(dead_time_s=30e-9, jitter_fwhm_s=200e-12)
    new = Scene(detector=Detector(dead_time_s=30e-9, jitter_fwhm_s=200e-12))
    assert new.dead_time_s == 30e-9 and new.sources == old.sources
    events_old, simulation_old = run(old, 20_000)
    events_new, simulation_new = run(new, 20_000)
    assert len(events_old) > 1000
    assert np.array_equal(events_old, events_new)
    assert np.array_equal(simulation_old.counts, simulation_new.counts)


@pytest.mark.parametrize("paralysable", [False, True])
def test_count_rate_under_either_dead_time(paralysable):
    # Period 32 cycles = 400 ns < 409.6 ns: the windows tile time and the SPAD sees one
    # stationary Poisson stream of rate n. Non-paralysable it counts m = n / (1 + n tau),
    # paralysable m = n exp(-n tau): 0.667 n and 0.607 n at n tau = 0.5. (A diffusion tail,
    # which touches no background photon, sends the non-paralysable case through the
    # detector path too.)
    rate_hz, tau_s, cycles = 1e7, 50e-9, 25_000
    detector = Detector(dead_time_s=tau_s, paralysable=paralysable, tail_fraction=0.5,
                        tail_s=1e-9)
    scene = Scene(victim=Settings(period=32), detections_per_pulse=0.0, background_hz=rate_hz,
                  detector=detector)
    _, simulation = run(scene, cycles)
    arrived = counter(simulation, "background", "generated") - \
        counter(simulation, "background", "outside")
    counted = detected(simulation, "background")
    x = rate_hz * tau_s
    expected = arrived * (math.exp(-x) if paralysable else 1 / (1 + x))
    assert arrived > 90_000
    # The counts of a dead-time-limited stream vary less than a Poisson number's
    assert within(counted, expected, math.sqrt(expected)), (counted, expected)


def test_pdp_thins_signal_and_ambient_light_but_not_dark_counts():
    # Signal m = 0.5 photons per pulse, PDP 0.3: a pulse gives a detection with probability
    # 1 - exp(-0.3 m) (0.139; 0.393 without the PDP). Ambient light 1 MHz thinned to
    # 0.3 MHz, dark counts 2e5 Hz not: per span (window 409.6 ns + dead time 20 ns before it)
    # (0.3e6 + 2e5) * 429.6 ns photons on average.
    cycles, m, pdp = 40_000, 0.5, 0.3
    detector = Detector(pdp=pdp, dark_count_hz=2e5)
    scene = Scene(detections_per_pulse=m, background_hz=1e6, detector=detector)
    _, simulation = run(scene, cycles)
    p = 1 - math.exp(-pdp * m)
    assert within(detected(simulation, "signal"), cycles * p, math.sqrt(cycles * p * (1 - p)))
    mean = (1e6 * pdp + 2e5) * (CODES * LSB_S + 20e-9) * cycles
    assert within(counter(simulation, "background", "generated"), mean, math.sqrt(mean))


def test_hot_pixels_and_the_log_normal_spread_of_dark_counts():
    # Pixel rates: median 100 Hz with a log-normal spread sigma = 0.5, 5 % hot pixels at a
    # median 1e5 Hz. Fraction of pixels above 1e4 Hz: 0.05 P(Z > ln(0.1) / 0.5) + 0.95
    # P(Z > ln(100) / 0.5); below 100 Hz: 0.95 / 2 + 0.05 P(Z < ln(1e-3) / 0.5).
    detector = Detector(dark_count_hz=100.0, dark_spread=0.5, hot_fraction=0.05,
                        hot_dark_count_hz=1e5, dark_seed=7)
    pixels = 200_000
    rates = detector.dark_rates(pixels)
    above = 0.05 * (1 - phi(math.log(0.1) / 0.5)) + 0.95 * (1 - phi(math.log(100) / 0.5))
    below = 0.95 * 0.5 + 0.05 * phi(math.log(1e-3) / 0.5)
    for observed, p in ((np.count_nonzero(rates > 1e4), above),
                        (np.count_nonzero(rates < 100.0), below)):
        assert within(observed, pixels * p, math.sqrt(pixels * p * (1 - p))), (observed, p)
    # A sensor's map is fixed by its seed, pixel 0 first whatever the number of pixels
    assert np.array_equal(detector.dark_rates(64), rates[:64])


def test_each_pixel_gets_its_own_dark_count_rate():
    # 64 pixels, no light, no dead time: pixel i's dark counts in the spans (one window of
    # 409.6 ns per laser cycle) are Poisson of mean rate_i * cycles * 409.6 ns, whatever the
    # PDP. Half the pixels hot (1 MHz) against 10 kHz: a simulator that spread the dark
    # counts evenly would miss every pixel by far.
    detector = Detector(dead_time_s=0.0, pdp=0.5, dark_count_hz=1e4, dark_spread=0.3,
                        hot_fraction=0.5, hot_dark_count_hz=1e6, dark_seed=3)
    pixels = PixelArray(distance_m=np.full(64, 4.0), sensor="per_pixel")
    cycles = 20_000
    scene = Scene(detections_per_pulse=0.0, background_hz=0.0, pixels=pixels,
                  detector=detector)
    _, simulation = run(scene, cycles)
    generated = simulation.pixel_counts[:, 1, COUNTERS.index("generated")]
    mean = detector.dark_rates(64) * cycles * CODES * LSB_S
    assert 5 < np.count_nonzero(mean > 1e3) < 60
    assert np.all(np.abs(generated - mean) <= 5 * np.sqrt(mean)), (generated, mean)


def emg_cdf(x, sigma, fraction, tau):
    """CDF of a Gaussian of ``sigma`` plus, with probability ``fraction``, an exponential
    delay of mean ``tau``: Phi(x / s) - f exp(s^2 / 2 tau^2 - x / tau) Phi(x / s - s / tau)."""
    return phi(x / sigma) - fraction * math.exp(sigma ** 2 / (2 * tau ** 2) - x / tau) * \
        phi(x / sigma - sigma / tau)


def test_timing_response_is_a_gaussian_with_an_exponential_tail():
    # Pulse 0.5 ns and jitter 0.1 ns FWHM (4.33 codes RMS together), 30 % of the photons late
    # by an exponential of 2 ns (40 codes). The 20 ns dead time lets the first photon of a
    # pulse only: with m photons on average, per photon CDF F, the recorded one has the CDF
    # (1 - exp(-m F)) / (1 - exp(-m)).
    m, fraction, tau = 0.1, 0.3, 2e-9 / LSB_S
    sigma = math.hypot(0.5, 0.1) / (2 * math.sqrt(2 * math.log(2))) * 1e-9 / LSB_S
    detector = Detector(jitter_fwhm_s=0.1e-9, tail_fraction=fraction, tail_s=2e-9)
    scene = Scene(detections_per_pulse=m, fwhm_s=0.5e-9, background_hz=0.0, detector=detector)
    events, _ = run(scene, 200_000)
    centre = time_of_flight(4.0) / LSB_S
    stamps = events["timestamp"].astype(np.int64)

    def first(x):
        return (1 - math.exp(-m * emg_cdf(x, sigma, fraction, tau))) / (1 - math.exp(-m))

    edges = np.concatenate(([-10_000], np.arange(int(centre - 3 * sigma), int(centre + 8 * tau),
                                                  4), [100_000]))
    observed = np.histogram(stamps, bins=edges)[0]
    expected = len(stamps) * np.diff([first(edge - centre) for edge in edges])
    # merge the bins expecting fewer than 10 into their neighbours toward the peak
    keep = expected >= 10
    value, bound = chi_square(observed[keep], expected[keep] * observed[keep].sum()
                              / expected[keep].sum())
    assert len(stamps) > 15_000 and value < bound, (value, bound)
    # The share of the tail: later than 5 sigma, only the tail remains
    late = np.count_nonzero(stamps >= math.ceil(centre + 5 * sigma))
    p = 1 - first(math.ceil(centre + 5 * sigma) - centre)
    assert within(late, len(stamps) * p, math.sqrt(len(stamps) * p)), (late, len(stamps) * p)


def test_afterpulse_delays_follow_their_exponentials():
    # The delay of an afterpulse: with weights w_k and means tau_k, P(delay > d) =
    # sum_k w_k exp(-d / tau_k).
    detector = Detector(afterpulse_probability=0.5, afterpulse_s=(5e-9, 50e-9),
                        afterpulse_weights=(3.0, 2.0))
    avalanches = Avalanches(detector, np.random.default_rng(5).spawn(4), None, 2)
    parents = np.arange(200_000)
    times, sources, _, owners = avalanches._children(np.zeros(len(parents)),
                                                     np.zeros(len(parents), np.int16), parents)
    assert within(len(times), 0.5 * len(parents), math.sqrt(0.25 * len(parents)))
    assert np.all(sources == 2) and np.all(np.diff(owners) > 0)
    edges = np.concatenate((np.arange(0, 300e-9, 5e-9), [np.inf])) / LSB_S
    survival = 0.6 * np.exp(-edges * LSB_S / 5e-9) + 0.4 * np.exp(-edges * LSB_S / 50e-9)
    value, bound = chi_square(np.histogram(times, bins=edges)[0], -np.diff(survival) * len(times))
    assert value < bound, (value, bound)


@pytest.mark.parametrize("paralysable", [False, True])
def test_afterpulse_share_is_a_geometric_series(paralysable):
    # Isolated pulses (1 us apart, window 409.6 ns), echo only, m = 0.1. Each avalanche gives
    # an afterpulse with probability P = 0.3 after 5 ns (w 0.6) or 50 ns (w 0.4).
    # Non-paralysable, one is an avalanche only after the dead time (10 ns): with probability
    # q = P sum_k w_k exp(-10 / tau_k); paralysable, always (q = P), counted after the dead
    # time. Avalanches that afterpulse again: per primary avalanche q / (1 - q) afterpulse
    # avalanches, P / (1 - q) afterpulses born (q alone without the chain).
    P, tau_d = 0.3, 10e-9
    survive = 0.6 * math.exp(-tau_d / 5e-9) + 0.4 * math.exp(-tau_d / 50e-9)
    detector = Detector(dead_time_s=tau_d, paralysable=paralysable, afterpulse_probability=P,
                        afterpulse_s=(5e-9, 50e-9), afterpulse_weights=(0.6, 0.4))
    scene = Scene(detections_per_pulse=0.1, fwhm_s=0.2e-9, background_hz=0.0,
                  detector=detector)
    _, simulation = run(scene, 400_000)
    # Primary avalanches: the echo's detections; paralysable, every echo photon in a window
    primaries = counter(simulation, "signal", "generated") - \
        counter(simulation, "signal", "outside") if paralysable else \
        detected(simulation, "signal")
    born = counter(simulation, "afterpulse", "generated")
    q = P if paralysable else P * survive
    # Avalanches of afterpulses per primary avalanche: K geometric, P(K = k) = (1 - q) q^k
    avalanches = born if paralysable else detected(simulation, "afterpulse")
    assert within(avalanches, primaries * q / (1 - q), math.sqrt(primaries * q / (1 - q) ** 2))
    assert within(born, primaries * P / (1 - q), math.sqrt(primaries * P / (1 - q) ** 2))
    if paralysable:
        # counted: those at least a dead time after the avalanche before (the parent)
        counted = detected(simulation, "afterpulse")
        expected = primaries * P * survive / (1 - q)
        assert within(counted, expected, math.sqrt(expected))


def erlang_cdf(n, rate, y):
    if y <= 0:
        return 0.0
    return 1.0 - math.exp(-rate * y) * sum((rate * y) ** k / math.factorial(k) for k in range(n))


def test_afterpulse_time_law_after_the_dead_time():
    # One exponential of 20 ns, dead time 10 ns, P = 0.2: an afterpulse that is an avalanche
    # comes tau_d + Exp(20 ns) after the avalanche before it (memoryless), q = P exp(-1/2) of
    # them per avalanche. The TDC keeps the last avalanche of the window: with N >= 1
    # afterpulse avalanches, P(N = n | N >= 1) = (1 - q) q^(n - 1), the last one comes
    # n tau_d + Erlang(n, 20 ns) after the primary.
    P, tau_d, tau = 0.2, 10e-9 / LSB_S, 20e-9 / LSB_S
    q = P * math.exp(-tau_d / tau)
    detector = Detector(dead_time_s=10e-9, jitter_fwhm_s=0.0, afterpulse_probability=P,
                        afterpulse_s=20e-9)
    scene = Scene(detections_per_pulse=0.2, fwhm_s=50e-12, background_hz=0.0,
                  detector=detector)
    events, simulation = run(scene, 300_000)
    centre = time_of_flight(4.0) / LSB_S
    primaries = detected(simulation, "signal")
    late = events["timestamp"][events["timestamp"] > centre + tau_d / 2].astype(np.int64)
    assert within(len(late), primaries * q, math.sqrt(primaries * q))

    def cdf(x):
        return sum((1 - q) * q ** (n - 1) * erlang_cdf(n, 1 / tau, x - n * tau_d)
                   for n in range(1, 30))

    edges = np.concatenate((np.arange(int(centre + tau_d), int(centre + tau_d + 8 * tau), 40),
                            [CODES]))
    expected = len(late) * np.diff([cdf(edge - centre) for edge in edges])
    value, bound = chi_square(np.histogram(late, bins=edges)[0], expected)
    assert value < bound, (value, bound)


def crosstalk_scene(count, columns, lit, detector, m=0.3):
    reflectivity = np.zeros(count)
    reflectivity[lit] = 1.0
    pixels = PixelArray(distance_m=np.full(count, 4.0), reflectivity=reflectivity,
                        sensor="per_pixel", columns=columns)
    return Scene(detections_per_pulse=m, background_hz=0.0, pixels=pixels, detector=detector)


def test_crosstalk_pair_rate_of_a_column():
    # Two pixels of a column, only pixel 0 lit (m = 0.3 per pulse): it fires in a fraction
    # 1 - exp(-m) of the cycles, and each time fires pixel 1 with p = 0.1 (orthogonal), within
    # the jitter (the crosstalk back to pixel 0 finds it dead). Pairs: cycles (1 - e^-m) p.
    cycles, m, p = 100_000, 0.3, 0.1
    detector = Detector(crosstalk_orthogonal=p, crosstalk_diagonal=0.5)
    events, simulation = run(crosstalk_scene(2, 1, [0], detector, m), cycles)
    first = events[events["address"] == 0]
    second = events[events["address"] == 1]
    pairs, at_first, at_second = np.intersect1d(first["pulse"], second["pulse"],
                                                return_indices=True)
    rate = (1 - math.exp(-m)) * p
    assert len(pairs) == len(second)
    assert within(len(pairs), cycles * rate, math.sqrt(cycles * rate * (1 - rate)))
    # simultaneous within the jitter (0.1 ns FWHM: 0.85 codes RMS), never before
    gap = second["timestamp"][at_second].astype(int) - first["timestamp"][at_first].astype(int)
    assert gap.min() >= 0 and gap.max() <= 6
    assert counter(simulation, "crosstalk", "generated") >= len(pairs)


def test_crosstalk_diagonal_only_reaches_the_diagonal():
    # A 2 x 2 grid, pixel 0 lit, diagonal crosstalk only: pixel 3 fires in (1 - e^-m) p of
    # the cycles, pixels 1 and 2 never.
    cycles, m, p = 100_000, 0.3, 0.1
    detector = Detector(crosstalk_diagonal=p)
    events, _ = run(crosstalk_scene(4, 2, [0], detector, m), cycles)
    rate = (1 - math.exp(-m)) * p
    assert np.count_nonzero(np.isin(events["address"], [1, 2])) == 0
    observed = np.count_nonzero(events["address"] == 3)
    assert within(observed, cycles * rate, math.sqrt(cycles * rate * (1 - rate)))


def test_crosstalk_chains_reach_as_a_random_graph_says():
    # A 2 x 2 grid, pixel 0 lit, orthogonal 0.3 and diagonal 0.2: every pixel that fires tries
    # each neighbour once; a pixel fires if any link into it from a fired pixel opens (a
    # second one finds it dead). P(pixel j fires | pixel 0 fired): summed over the 2^12
    # states of the directed links, of those that reach j from 0.
    cycles, m, po, pd = 60_000, 0.3, 0.3, 0.2
    links = [(a, b) for a in range(4) for b in range(4) if a != b]

    def chance(a, b):
        return pd if {a, b} in ({0, 3}, {1, 2}) else po

    reach = np.zeros(4)
    for state in itertools.product((False, True), repeat=len(links)):
        weight = math.prod(chance(*link) if on else 1 - chance(*link)
                           for link, on in zip(links, state))
        fired, grown = {0}, True
        while grown:
            new = {b for (a, b), on in zip(links, state) if on and a in fired} - fired
            fired |= new
            grown = bool(new)
        for j in fired:
            reach[j] += weight
    detector = Detector(crosstalk_orthogonal=po, crosstalk_diagonal=pd)
    events, _ = run(crosstalk_scene(4, 2, [0], detector, m), cycles)
    for j in (1, 2, 3):
        rate = (1 - math.exp(-m)) * reach[j]
        observed = np.count_nonzero(events["address"] == j)
        assert within(observed, cycles * rate, math.sqrt(cycles * rate * (1 - rate))), \
            (j, observed, cycles * rate)


def test_neighbours_follow_the_layout():
    orthogonal, diagonal = PixelArray(distance_m=np.full(9, 4.0), columns=3).neighbours()
    assert sorted(orthogonal[4]) == [1, 3, 5, 7] and sorted(diagonal[4]) == [0, 2, 6, 8]
    assert sorted(orthogonal[0]) == [-1, -1, 1, 3] and sorted(diagonal[0]) == [-1, -1, -1, 4]
    orthogonal, diagonal = PixelArray(distance_m=np.full(5, 4.0)).neighbours()
    assert sorted(orthogonal[2]) == [-1, -1, 1, 3] and np.all(diagonal == -1)


def test_a_run_with_every_effect_keeps_every_photon_counted():
    # generated = outside + dead + overwritten + recorded for every source, and the carried
    # photons are counted once: over the same cycles, steps of one cycle count what steps of
    # many do, within their statistics (the children's draws follow the steps).
    detector = Detector(pdp=0.5, dark_count_hz=1e3, hot_fraction=0.2, hot_dark_count_hz=1e6,
                        paralysable=True, tail_fraction=0.2, tail_s=1e-9,
                        afterpulse_probability=0.1, afterpulse_s=(20e-9,),
                        crosstalk_orthogonal=0.05, crosstalk_diagonal=0.01)
    pixels = PixelArray(distance_m=np.full(16, 4.0), sensor="column", columns=4)
    scene = Scene(detections_per_pulse=0.5, background_hz=1e5, pixels=pixels,
                  detector=detector)
    totals = []
    for chunk_cycles in (1 << 12, 1):
        _, simulation = run(scene, 4000, chunk_cycles=chunk_cycles)
        counts = simulation.counts
        assert np.array_equal(counts[:, 0], counts[:, 1:].sum(axis=1))
        totals.append(counts[:, 0])
    assert np.all(np.abs(totals[0] - totals[1]) <= 5 * np.sqrt(2 * totals[0] + 1))


@pytest.mark.parametrize("options, message", [
    (dict(pdp=0), "Photon detection probability must be above 0"),
    (dict(pdp=1.5), "Photon detection probability must be a probability from 0 to 1, not 1.5"),
    (dict(dark_count_hz=-1), "Dark count rate (Hz) must be a finite non-negative number, "
                             "not -1"),
    (dict(tail_fraction=0.1), "A diffusion tail needs a positive time constant (tail_s)"),
    (dict(afterpulse_probability=0.1), "Afterpulsing needs at least one time constant "
                                       "(afterpulse_s)"),
    (dict(afterpulse_s=(1e-9, 2e-9), afterpulse_weights=(1.0,)),
     "Give one afterpulse weight per time constant (2), not (1.0,)"),
    (dict(afterpulse_probability=1.0, afterpulse_s=1e-9),
     "Afterpulse probability must be below 1 (each afterpulse can afterpulse again)"),
    (dict(paralysable="yes"), "Paralysable must be True or False, not 'yes'"),
    (dict(crosstalk_diagonal=2), "Diagonal crosstalk probability must be a probability from "
                                 "0 to 1, not 2"),
    (dict(dark_seed=-1), "Dark count seed must be a non-negative integer, not -1"),
])
def test_bad_detectors_are_refused(options, message):
    with pytest.raises(ValueError) as error:
        Detector(**options)
    assert str(error.value) == message


def test_scene_and_detector_disagreeing_is_refused():
    with pytest.raises(ValueError) as error:
        Scene(dead_time_s=30e-9, detector=Detector(dead_time_s=50e-9))
    assert str(error.value) == ("The scene's dead_time_s (3e-08) differs from its detector's "
                                "(5e-08): set it in the detector")
    with pytest.raises(ValueError) as error:
        Scene(detector="fast")
    assert str(error.value) == "Scene detector must be a Detector or None, not 'fast'"
    with pytest.raises(ValueError) as error:
        PixelArray(distance_m=np.full(6, 4.0), columns=4)
    assert str(error.value) == ("The pixels' columns must be a positive integer that divides "
                                "the 6 pixels, not 4")


def test_every_preset_has_its_sources_in_the_docs():
    table = (Path(__file__).resolve().parents[2] / "docs" / "scene.md").read_text()
    assert set(PRESETS) == {"paper", "spcm20a", "linospad2"}
    for name, detector in PRESETS.items():
        assert isinstance(detector, Detector)
        assert f"| `{name}` |" in table, name
    # A column of LinoSPAD2 pixels: its nearest neighbours are the orthogonal ones
    assert PRESETS["linospad2"].crosstalk_diagonal == 0


def test_dark_count_map_gives_the_same_run_in_plain_python_and_numpy():
    # Fed starts, one to three laser cycles a step, as in closed loop: photons made and
    # resolved in plain Python (steps of a few cycles and photons) against numpy for every
    # step, on the same draws, with each pixel's own dark count rate (hot pixels) and a PDP.
    detector = Detector(pdp=0.5, dark_count_hz=1e5, dark_spread=0.5, hot_fraction=0.3,
                        hot_dark_count_hz=3e6, dark_seed=2)
    pixels = PixelArray(distance_m=np.full(6, 4.0), sensor="column")
    scene = Scene(detections_per_pulse=0.3, background_hz=1e5, pixels=pixels,
                  detector=detector, dead_time_s=20e-9)
    steps = 1500
    starts = 100 + np.cumsum(np.random.default_rng(7).integers(20, 121, 3 * steps + 1))
    runs = []
    for quiet_cycles, few_photons in ((None, None), (0, -1)):
        simulation = simulation_for(scene, seed=4, chunk_cycles=64, external_starts=True)
        if quiet_cycles is not None:
            simulation.quiet_cycles, simulation.few_photons = quiet_cycles, few_photons
        simulation.feed(starts)
        events = [simulation.step(1 + index % 3).events for index in range(steps)]
        runs.append((np.concatenate(events), simulation.pixel_counts.copy()))
    (events, counts), (reference, reference_counts) = runs
    background = reference_counts[:, 1, COUNTERS.index("generated")]
    assert len(reference) > steps // 2 and background.max() > 5 * background.min()
    assert np.array_equal(events, reference)
    assert np.array_equal(counts, reference_counts)
