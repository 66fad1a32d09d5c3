"""Physics sanity of the photon-level scene simulator.

Every expectation is worked out here from the physics (Poisson statistics, the non-paralysable
dead-time formula, equation 6 of the paper), not taken from the simulator.
"""

import math

import numpy as np
import pytest

from fliss.hdl.event import TDC_LSB_S
from fliss.sim.models import delay as delay_model
from fliss.sim.models import scheduler
from fliss.sim.models.delay import DelayStream
from fliss.protocol.events import EVENT_DTYPE, pack
from fliss.sim.scene import (COUNTERS, Aggressor, Scene, Simulation, acquire, histogram,
                             line_pixels, simulation_for)
from fliss.sim.models.scheduler import Settings


C = 299_792_458.0
CLOCK_NS = 12.5
CODES = 8192


def sigma_ns(fwhm_ns=2.1, jitter_fwhm_ns=0.1):
    return math.hypot(fwhm_ns, jitter_fwhm_ns) / (2 * math.sqrt(2 * math.log(2)))


def run_events(scene, cycles, seed=1, chunk_cycles=1 << 14):
    simulation = Simulation(scene, seed=seed, chunk_cycles=chunk_cycles)
    chunks = list(simulation.chunks(cycles))
    events = np.concatenate([chunk.events for chunk in chunks])
    starts = np.concatenate([chunk.start_cycles for chunk in chunks])
    return events, starts, simulation.counts


def z_score(observed, expected):
    return (observed - expected) / math.sqrt(expected)


@pytest.mark.parametrize("mode, setting", [
    ("off", {}), ("mseq", {"length": 4}), ("mseq", {"length": 18}),
    ("masked", {"mask_width": 6}), ("masked", {"mask_width": 1})])
def test_delay_stream_continues_the_reference_sequence(mode, setting):
    stream = DelayStream(mode, seed=5, block=1024, **setting)
    parts = [stream.take(count) for count in (1, 1023, 3000, 7, 2500)]
    expected = delay_model.delays(mode, 6531, seed=5, **setting)
    assert np.array_equal(np.concatenate(parts), expected)


def test_victim_fires_when_the_reference_scheduler_says():
    victim = Settings(mode="masked", mask_width=5, seed=77, period=80)
    _, starts, _ = run_events(Scene(victim=victim), 50_000, chunk_cycles=4096)
    delays = delay_model.delays("masked", 50_000, mask_width=5, seed=77)
    assert np.array_equal(starts, scheduler.fire_cycles(delays, 80) + scheduler.LATENCY)


@pytest.mark.parametrize("keep", ["first", "last"])
def test_poisson_background_level(keep):
    # Background only, no dead time: in each window of N codes of width d the photon counts per
    # code are independent Poisson(r d). The last photon falls in code b when b has one and no
    # later code has any: (1 - exp(-r d)) exp(-r d (N - 1 - b)); the first, mirrored.
    rate_hz, cycles = 2e6, 60_000
    scene = Scene(detections_per_pulse=0.0, background_hz=rate_hz, dead_time_s=0.0, keep=keep)
    events, _, counts = run_events(scene, cycles)
    mu = rate_hz * TDC_LSB_S
    codes = np.arange(CODES)
    after = CODES - 1 - codes if keep == "last" else codes
    expected = cycles * (1 - math.exp(-mu)) * np.exp(-mu * after)
    observed = histogram(events)
    blocks = observed.reshape(16, -1).sum(axis=1)
    expected_blocks = expected.reshape(16, -1).sum(axis=1)
    assert max(abs(z_score(o, e)) for o, e in zip(blocks, expected_blocks)) < 5
    # One event per window that saw a photon at all
    assert abs(z_score(len(events), cycles * (1 - math.exp(-mu * CODES)))) < 5
    # Photons drawn over the window of each cycle (no dead time before it)
    assert abs(z_score(counts[1, 0], cycles * mu * CODES)) < 5
    # Background rises (last) or falls (first) across the window by exp(mu * N)
    ratio = blocks[-1] / blocks[0]
    assert (ratio > 1) == (keep == "last")


def test_dead_time_count_loss_is_non_paralysable():
    # Period 32 cycles = 400 ns < 409.6 ns: each window ends at the next start, so the TDC
    # windows tile time and the detector sees one stationary Poisson stream. A non-paralysable
    # detector of dead time tau then counts r / (1 + r tau); a paralysable one would count
    # r exp(-r tau), 0.37 r instead of 0.5 r here.
    rate_hz, tau_s, cycles = 100e6, 10e-9, 20_000
    scene = Scene(victim=Settings(period=32), detections_per_pulse=0.0, background_hz=rate_hz,
                  dead_time_s=tau_s)
    _, _, counts = run_events(scene, cycles)
    generated, outside, dead, overwritten, recorded = counts[1]
    assert outside < 1e-3 * generated      # only before the first window
    detected_fraction = (overwritten + recorded) / (generated - outside)
    assert detected_fraction == pytest.approx(1 / (1 + rate_hz * tau_s), rel=0.01)


def aggressor_scene(victim, period_cycles, mean=0.05):
    return Scene(victim=victim, detections_per_pulse=0.0, background_hz=0.0, dead_time_s=0.0,
                 aggressors=(Aggressor(period_cycles=period_cycles, offset_s=75e-9,
                                       detections_per_pulse=mean),))


def test_aggressor_peak_sits_at_offset_plus_path_without_fliss():
    cycles, mean = 40_000, 0.05
    events, _, counts = run_events(aggressor_scene(Settings(period=80), 80, mean), cycles)
    # Same period, so aggressor pulse j rises 75 ns after victim pulse j and flies 2 z / c
    position_ns = 75.0 + 2 * 4.0 / C * 1e9
    stamps = events["timestamp"].astype(float)
    # floor() of the arrival time lowers the mean code by half a code
    assert stamps.mean() == pytest.approx(position_ns / 0.05 - 0.5, abs=0.5)
    assert stamps.std() == pytest.approx(sigma_ns() / 0.05, rel=0.03)
    # One aggressor pulse per window: an event whenever it gave at least one photon
    assert abs(z_score(len(events), cycles * (1 - math.exp(-mean)))) < 5
    assert counts[2, COUNTERS.index("outside")] == 0


def windowed_counts(events, centres_bins, half_width):
    stamps = events["timestamp"].astype(float)
    return np.array([np.count_nonzero(np.abs(stamps - c) < half_width) for c in centres_bins])


def test_fliss_spreads_the_aggressor_as_equation_6_says_and_loses_nothing():
    # Victim with a complete L = 3 m-sequence; the aggressor at the victim's effective period
    # T + E(R) = 80 + 3 cycles. Equation 6: aggressor pulse j lands at t_a + ToF - T_rnd, where
    # here T_rnd of pulse j is the accumulated lag sum_{i<=j} R_i - 3 j of the victim.
    L, mean, periods = 3, 0.05, 15_000
    sequence = (1 << L) - 1
    cycles = sequence * periods
    victim = Settings(mode="mseq", length=L, period=80)
    events, _, counts = run_events(aggressor_scene(victim, 83, mean), cycles)
    delays = delay_model.delays("mseq", sequence, length=L)
    lag_cycles = np.cumsum(delays) - 3 * np.arange(sequence)
    positions_ns = 75.0 + 2 * 4.0 / C * 1e9 - CLOCK_NS * lag_cycles
    assert positions_ns.min() > 5 and positions_ns.max() < 400   # all inside the window
    distinct, multiplicity = np.unique(np.round(positions_ns, 6), return_counts=True)
    per_pulse = 1 - math.exp(-mean)          # one aggressor pulse per window, no dead time
    expected = multiplicity * periods * per_pulse
    observed = windowed_counts(events, distinct / 0.05 - 0.5, 5 * sigma_ns() / 0.05)
    assert max(abs(z_score(o, e)) for o, e in zip(observed, expected)) < 5
    # Nothing created or lost: every aggressor photon is in a window; each event is one
    # aggressor pulse; the other photons of a pulse are overwritten by the single-hit TDC
    generated, outside, dead, overwritten, recorded = counts[2]
    assert outside == 0 and dead == 0
    assert recorded == len(events) == observed.sum()
    assert generated == recorded + overwritten
    assert abs(z_score(generated, mean * cycles)) < 5

    # Without FLISS (same number of pulses) the whole aggressor sits in one peak
    off_events, _, _ = run_events(aggressor_scene(Settings(period=80), 80, mean), cycles)
    off_peak = windowed_counts(off_events, [(75.0 + 2 * 4.0 / C * 1e9) / 0.05 - 0.5],
                               5 * sigma_ns() / 0.05)[0]
    assert abs(z_score(off_peak, cycles * per_pulse)) < 5
    drop = observed.max() / off_peak
    assert drop == pytest.approx(multiplicity.max() / sequence, rel=0.06)


@pytest.mark.parametrize("victim", [Settings(mode="mseq", length=6, period=80),
                                    Settings(mode="masked", mask_width=6, period=80)])
def test_victim_time_of_flight_moves_less_than_one_bin_with_fliss(victim):
    cycles = 300_000
    tof_bins = 2 * 4.0 / C / TDC_LSB_S
    centroids = []
    for settings in (Settings(period=80), victim):
        events, _, _ = run_events(Scene(victim=settings), cycles)
        stamps = events["timestamp"].astype(float)
        near = stamps[np.abs(stamps - tof_bins) < 5 * sigma_ns() / 0.05]
        # Flat background under the window, from the part of the histogram far from the peak
        centroids.append(near.mean())
    assert abs(centroids[1] - centroids[0]) < 1
    assert centroids[0] == pytest.approx(tof_bins - 0.5, abs=1)


def test_events_have_the_gateware_layout():
    scene = Scene(address=17, aggressors=(Aggressor(period_cycles=80),))
    events, starts, _ = run_events(scene, 5000)
    assert events.dtype == EVENT_DTYPE
    assert np.all(np.diff(events["pulse"].astype(np.int64)) > 0)   # at most one per cycle
    assert np.all(events["address"] == 17) and np.all(events["collision"] == 0)
    assert events["timestamp"].max() < CODES
    assert len(pack(events)) == len(events)


def test_acquisitions_split_the_run_by_tdc_start_time_and_keep_every_photon():
    victim = Settings(mode="masked", mask_width=4, seed=3, period=80)
    scene = Scene(victim=victim, aggressors=(Aggressor(period_cycles=87.5),))
    t_int_s, count = 1e-3, 4
    result = acquire(scene, t_int_s, count, seed=2, chunk_cycles=1000)
    t_int_cycles = 80_000
    delays = delay_model.delays("masked", 5000, mask_width=4, seed=3)
    starts = scheduler.fire_cycles(delays, 80) + scheduler.LATENCY
    expected = np.bincount(starts[starts < count * t_int_cycles] // t_int_cycles,
                           minlength=count)
    assert np.array_equal(result.cycles, expected)
    # Each photon counted once per source and acquisition
    assert np.array_equal(result.counts[..., 0], result.counts[..., 1:].sum(axis=-1))
    assert np.array_equal(result.histograms.sum(axis=1), result.counts[..., -1].sum(axis=1))


def test_bad_parameters_raise_with_a_clear_message():
    with pytest.raises(ValueError, match=r"^The TDC keeps the 'first' or the 'last' photon, "
                                         r"not 'middle'$"):
        Scene(keep="middle")
    with pytest.raises(ValueError, match=r"^Dead time \(s\) must be a finite non-negative "
                                         r"number, not -1e-09$"):
        Scene(dead_time_s=-1e-9)
    with pytest.raises(ValueError, match=r"^Aggressor period \(victim clock cycles\) must be a "
                                         r"finite positive number, not 0$"):
        Aggressor(period_cycles=0)
    with pytest.raises(ValueError, match=r"^An aggressor with its own delays needs a whole number "
                                         r"of clock cycles of at least 2 as period, not 87.5$"):
        Aggressor(period_cycles=87.5, mode="mseq", length=4)
    with pytest.raises(ValueError, match=r"^Pixel address must be an integer from 0 to 63, "
                                         r"not 64$"):
        Scene(address=64)
    with pytest.raises(ValueError, match=r"^Number of acquisitions must be a positive integer, "
                                         r"not 0$"):
        acquire(Scene(), 1e-3, 0)


def test_aggressor_with_its_own_delays_moves_by_them():
    # Victim without FLISS; the aggressor has its own L = 3 m-sequence in grid mode, so its pulse
    # j fires R[j] cycles after the victim's pulse j and lands at t_a + ToF + R[j] * 12.5 ns:
    # seven peaks 12.5 ns apart, one per delay value 0..6, each with 1/7 of the pulses.
    periods, mean = 6000, 0.05
    cycles = 7 * periods
    scene = Scene(detections_per_pulse=0.0, background_hz=0.0, dead_time_s=0.0,
                  aggressors=(Aggressor(period_cycles=80, detections_per_pulse=mean,
                                        mode="mseq", length=3, seed=5, grid=True),))
    events, _, counts = run_events(scene, cycles)
    positions_ns = 75.0 + 2 * 4.0 / C * 1e9 + CLOCK_NS * np.arange(7)
    observed = windowed_counts(events, positions_ns / 0.05 - 0.5, 5 * sigma_ns() / 0.05)
    expected = periods * (1 - math.exp(-mean))
    assert max(abs(z_score(o, expected)) for o in observed) < 5
    assert observed.sum() == len(events) == counts[2, COUNTERS.index("recorded")]


def test_two_aggressors_each_at_its_own_offset():
    cycles, mean = 20_000, 0.03
    scene = Scene(detections_per_pulse=0.0, background_hz=0.0, dead_time_s=0.0,
                  aggressors=(Aggressor(period_cycles=80, offset_s=75e-9,
                                        detections_per_pulse=mean),
                              Aggressor(period_cycles=80, offset_s=250e-9, fwhm_s=4.2e-9,
                                        detections_per_pulse=2 * mean)))
    events, _, counts = run_events(scene, cycles)
    stamps = events["timestamp"].astype(float)
    tof_ns = 2 * 4.0 / C * 1e9
    first = stamps[stamps < 3000]
    second = stamps[stamps >= 3000]
    # Each mean within 5 standard errors (about 0.5 and 1 code) of the pulse's arrival
    for stamps_of, arrival_ns in ((first, 75 + tof_ns), (second, 250 + tof_ns)):
        error = stamps_of.std() / math.sqrt(len(stamps_of))
        assert stamps_of.mean() == pytest.approx(arrival_ns / 0.05 - 0.5, abs=5 * error)
    assert second.std() == pytest.approx(sigma_ns(4.2) / 0.05, rel=0.05)
    # Each source keeps its own counters; the later pulse overwrites the earlier (last photon)
    p1, p2 = 1 - math.exp(-mean), 1 - math.exp(-2 * mean)
    assert abs(z_score(len(second), cycles * p2)) < 5
    assert abs(z_score(len(first), cycles * p1 * (1 - p2))) < 5
    assert counts[3, COUNTERS.index("recorded")] == len(second)


def test_memory_stays_bounded_however_long_the_run():
    import tracemalloc

    scene = Scene(victim=Settings(mode="mseq", length=5, period=80),
                  aggressors=(Aggressor(period_cycles=95),))
    peaks = []
    for cycles in (100_000, 1_000_000):
        simulation = Simulation(scene, seed=1, chunk_cycles=8192)
        tracemalloc.start()
        for _ in simulation.chunks(cycles):
            pass
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert peaks[1] < 1.5 * peaks[0]


#: Scene of the closed-loop tests: an m-sequence victim and a free-running aggressor.
CLOSED_LOOP_SCENE = Scene(victim=Settings(mode="mseq", length=5, period=80),
                          aggressors=(Aggressor(period_cycles=95),))


def test_fed_tdc_starts_give_the_same_run_as_the_scheduler_model():
    # Closed loop: the starts a gateware emits, fed in pieces, replace the reference scheduler.
    scene = CLOSED_LOOP_SCENE
    cycles = 30_000
    reference, starts, _ = run_events(scene, cycles, chunk_cycles=4096)
    fed = Simulation(scene, seed=1, chunk_cycles=4096, external_starts=True)
    delays = delay_model.delays("mseq", cycles + 1, length=5)
    edges = scheduler.fire_cycles(delays, 80) + scheduler.LATENCY
    for piece in np.array_split(edges, 7):
        fed.feed(piece)
    chunks = list(fed.chunks(cycles + 10))      # the last start fed has no successor yet
    assert sum(chunk.cycles for chunk in chunks) == cycles
    events = np.concatenate([chunk.events for chunk in chunks])
    assert np.array_equal(np.concatenate([c.start_cycles for c in chunks]), starts)
    assert np.array_equal(events, reference)
    for late in ([int(edges[-1])], int(edges[-1]), np.int64(edges[0])):   # array or integer
        with pytest.raises(ValueError, match=r"^TDC starts must increase strictly, also "
                                             r"across calls to feed\(\)$"):
            fed.feed(late)


def test_fed_aggressor_triggers_give_the_same_run_as_its_settings():
    # Closed loop for the aggressors: a free-running aggressor (period 95 cycles) fed as the
    # trigger edges it makes, 1 + LATENCY cycles after each of its nominal frame starts.
    scene = CLOSED_LOOP_SCENE
    cycles = 20_000
    reference, starts, reference_counts = run_events(scene, cycles, chunk_cycles=4096)
    fed = Simulation(scene, seed=1, chunk_cycles=4096, external_aggressors=True)
    edges = 1 + scheduler.LATENCY + 95 * np.arange(starts[-1] // 95 + 100)
    for piece in np.array_split(edges, 5):
        fed.feed_aggressor(0, piece)
    events = np.concatenate([chunk.events for chunk in fed.chunks(cycles)])
    assert np.array_equal(events, reference)
    assert np.array_equal(fed.counts, reference_counts)
    assert reference_counts[2].sum() > 100      # the aggressor's photons are in the run
    for late in (int(edges[-1]), int(edges[0])):    # also after the edges were used
        for given in ([late], late):
            with pytest.raises(ValueError, match=r"^Aggressor trigger edges must increase "):
                fed.feed_aggressor(0, given)
    with pytest.raises(ValueError, match=r"^Aggressor index must be from 0 to 0, not 1$"):
        fed.feed_aggressor(1, [int(edges[-1]) + 1])
    with pytest.raises(ValueError, match=r"^This simulation takes its aggressors from their "
                                         r"settings; create it with external_aggressors=True"):
        Simulation(scene).feed_aggressor(0, [1])


def test_starts_that_do_not_fire_only_close_a_window():
    # Starts every 80 cycles, the victim firing with every other one: its echo (26.7 ns, 2.1
    # cycles) is only in the windows of the starts it fired with. No background, no dead time.
    scene = Scene(background_hz=0, dead_time_s=0, detections_per_pulse=0.5)
    fed = Simulation(scene, seed=3, chunk_cycles=256, external_starts=True)
    starts = 80 * np.arange(1, 4001)
    for index, start in enumerate(starts):
        fed.feed([start], fired=index % 2 == 0)
    events = np.concatenate([chunk.events for chunk in fed.chunks(4000)])
    assert len(events) > 500
    assert np.all(events["pulse"] % 2 == 0)
    tof_codes = scene.tof_s / TDC_LSB_S
    assert abs(np.median(events["timestamp"]) - tof_codes) < 5


@pytest.mark.parametrize("keep, fed, sensor", [
    ("last", True, None), ("first", True, None), ("last", False, None),
    ("last", True, "column"), ("first", True, "column"), ("last", False, "per_pixel"),
    ("first", True, "per_pixel")])
def test_steps_of_few_photons_in_plain_python_give_what_numpy_gives(keep, fed, sensor):
    # One to three laser cycles a step, as in closed loop: the plain-Python detection (steps
    # of a few photons) and numpy's, on the same draws, for one pixel and for 6 pixels (two
    # at 2.5 m, the others at 4 m: collisions on the column). A strong echo, background and an
    # aggressor put several photons in a window and the dead time blocks some; fed starts 20
    # to 120 cycles apart cut some windows short (with the scheduler's starts, spans never
    # meet).
    pixels = None if sensor is None else line_pixels(pixels=6, object_pixels=(2, 4),
                                                     sensor=sensor)
    scene = Scene(detections_per_pulse=1.5 if sensor is None else 0.6,
                  background_hz=6e7 if sensor is None else 3e6, keep=keep, address=3,
                  pixels=pixels, dead_time_s=150e-9,
                  aggressors=(Aggressor(period_cycles=95, detections_per_pulse=1.0),))
    steps = 1500
    starts = 100 + np.cumsum(np.random.default_rng(7).integers(20, 121, 3 * steps + 1))
    runs = []
    for few_photons in (Simulation.few_photons, -1):
        simulation = simulation_for(scene, seed=4, chunk_cycles=64, external_starts=fed)
        simulation.few_photons = few_photons
        if fed:
            simulation.feed(starts)
        plain = 0
        events = []
        for index in range(steps):
            chunk = simulation.step(1 + index % 3)
            events.append(chunk.events)
            plain += chunk.counts[:, COUNTERS.index("generated")].sum() <= few_photons
        runs.append((np.concatenate(events), simulation.counts.copy(), plain))
    (events, counts, plain), (reference, reference_counts, _) = runs
    assert steps // 4 < plain < steps            # both paths taken
    assert len(reference) > steps // 2
    assert counts[:, COUNTERS.index("dead")].sum() > 100
    if sensor == "column":
        assert reference["collision"].sum() > 50
    assert np.array_equal(events, reference)
    assert np.array_equal(counts, reference_counts)


@pytest.mark.parametrize("sensor", [None, "column"])
def test_steps_without_photons_in_plain_python_give_what_numpy_gives(sensor):
    # Closed loop as the virtual boards run it: fed starts and aggressor triggers, one to three
    # laser cycles a step, most of them without a photon. The short path of those steps
    # (quiet_cycles) against the full path for every step, on the same draws.
    pixels = None if sensor is None else line_pixels(pixels=6, object_pixels=(2, 4),
                                                     sensor=sensor)
    scene = Scene(detections_per_pulse=0.05, background_hz=2e5, pixels=pixels,
                  aggressors=(Aggressor(period_cycles=80, detections_per_pulse=0.05,
                                        jitter_s=2e-9),))
    steps = 3000
    starts = 100 + np.cumsum(np.random.default_rng(7).integers(20, 121, 3 * steps + 1))
    runs = []
    for quiet_cycles in (Simulation.quiet_cycles, 0):
        simulation = simulation_for(scene, seed=4, chunk_cycles=64, external_starts=True,
                                    external_aggressors=True)
        simulation.quiet_cycles = quiet_cycles
        simulation.feed(starts)
        simulation.feed_aggressor(0, 60 + 80 * np.arange(starts[-1] // 80))
        quiet, events = 0, []
        for index in range(steps):
            chunk = simulation.step(1 + index % 3)
            events.append(chunk.events)
            quiet += not chunk.counts.any()
        runs.append((np.concatenate(events), simulation.counts.copy(), quiet))
    (events, counts, quiet), (reference, reference_counts, _) = runs
    assert steps // 10 < quiet < steps               # both paths taken
    assert len(reference) > steps // 10
    assert reference_counts[:, COUNTERS.index("generated")].all()   # every source's photons
    assert np.array_equal(events, reference)
    assert np.array_equal(counts, reference_counts)


@pytest.mark.parametrize("mean", [0.004, 0.05, 0.7, 3.0])
def test_counts_drawn_ahead_are_poisson(mean):
    # Hits draws a small mean's counts as the gaps between non-zero counts and their values
    # (conditioned on at least one), a larger one pulse by pulse: either way each pulse's
    # count is Poisson, independent of the others. Taken in pieces of uneven length.
    from fliss.sim.scene.draws import Hits
    hits = Hits(np.random.default_rng(11), mean)
    pulses = 1_000_000
    counts = np.zeros(pulses, dtype=np.int64)
    taken = 0
    for piece in np.random.default_rng(12).integers(1, 5000, pulses // 2500):
        piece = min(int(piece), pulses - taken)
        offsets, numbers = hits.take(piece)
        assert np.all(numbers > 0) and np.all(np.diff(offsets) > 0)
        counts[taken + offsets] = numbers
        taken += piece
    counts = counts[:taken]
    for k in range(4):
        p = math.exp(-mean) * mean ** k / math.factorial(k)
        if taken * p > 20:              # (the rarer counts seen too seldom to tell)
            error = math.sqrt(taken * p * (1 - p))
            assert abs(np.count_nonzero(counts == k) - taken * p) < 5 * error, k
    assert abs(z_score(counts.sum(), taken * mean)) < 5
    # neighbours independent: the covariance of consecutive counts is zero
    covariance = np.mean((counts[1:] - mean) * (counts[:-1] - mean))
    assert abs(covariance) < 5 * mean / math.sqrt(taken)
