"""The interference schemes of fliss.sim.studies.schemes against closed forms: accidental
k-of-n coincidences of Poisson background, the share of an unrelated laser's pulses that land
in the victim's gates, a Golomb code's correlation peak and sidelobes, and the energy a frame
sends."""

import math

import numpy as np
import pytest

from fliss.hdl.event import TDC_LSB_S
from fliss.sim.scene import Detector
from fliss.sim.studies.schemes import PARAMETERS, check_point, evaluate, pulses_per_frame
from fliss.sim.studies.schemes.emitters import (Camera, LSB_PER_CYCLE, golomb_code,
                                                mean_period_cycles)
from fliss.sim.studies.schemes.macropixel import avalanches, coincidences, correlate, tdc


def _accidental_rate(n, k, rate_hz, window_s):
    """Rate of k-of-n coincidences of n SPADs with Poisson light of ``rate_hz`` each and a
    non-paralysable dead time equal to the window: a SPAD counts at r' = r / (1 + r tau); a
    count fires the gate when exactly k - 1 of the other n - 1 SPADs counted in the window
    before it, each with probability q = r' tau (at most one count fits in the window)."""
    counted = rate_hz / (1 + rate_hz * window_s)
    q = counted * window_s
    return n * counted * math.comb(n - 1, k - 1) * q ** (k - 1) * (1 - q) ** (n - k)


@pytest.mark.parametrize("n, k", [(4, 2), (4, 3), (8, 2)])
def test_accidental_coincidences_follow_the_binomial_law(n, k):
    rng = np.random.default_rng([n, k])
    rate, window, duration = 5e6, 20e-9, 4e-3
    detector = Detector(dead_time_s=window)
    count = rng.poisson(n * rate * duration)
    times = np.sort(rng.uniform(0, duration / TDC_LSB_S, count))
    spads = rng.integers(0, n, count)
    counted, _ = avalanches(times, np.ones(count, dtype=np.int16), spads, detector, n, rng, 2)
    fired = coincidences(counted, k, window / TDC_LSB_S).sum()
    expected = _accidental_rate(n, k, rate, window) * duration
    assert abs(fired - expected) < 4 * math.sqrt(expected) + 0.01 * expected, (fired, expected)


def test_one_of_one_passes_every_count():
    times = np.array([0.0, 5.0, 100.0])
    assert coincidences(times, 1, 50.0).all()
    # Two of n: the second count within the window fires, the first and a third do not
    assert coincidences(np.array([0.0, 5.0, 7.0, 100.0]), 2, 10.0).tolist() == \
        [False, True, False, False]


def _landing_share(point, victim_seed, aggressor_seed, ppm=None):
    """Share of an aggressor's pulses over a 10 ms frame that fall in the victim's gates."""
    point = check_point(point)
    victim = Camera.draw(point, np.random.default_rng(victim_seed), victim=True)
    aggressor = Camera.draw(point, np.random.default_rng(aggressor_seed))
    if ppm is not None:
        aggressor.ppm = ppm
    frame = point["t_int_s"] / TDC_LSB_S
    starts = victim.bursts(0.0, frame)
    pulses = aggressor.pulses(0.0, frame - 2 * 8192)
    inside, _ = tdc(np.sort(pulses), starts, 8192, multi=True)
    return len(inside) / len(pulses), starts


def test_an_unrelated_fixed_period_lands_in_the_gate_as_its_length_over_the_period():
    # 1000 ppm: the aggressor walks 20 codes a pulse, over the whole period 10 times a frame
    # (the share is exact over whole walks); at any phase
    shares = [_landing_share(dict(scheme="none"), 1, seed, ppm)[0]
              for seed in range(4, 8) for ppm in (1000.0, -1000.0)]
    expected = 8192 / (80 * LSB_PER_CYCLE)
    assert all(abs(share - expected) < 0.002 for share in shares), (shares, expected)


def test_prf_hopping_lands_in_the_gate_as_its_length_over_the_mean_period():
    # An aggressor independent of the victim lands in its gates as the gates' share of the
    # victim's time: 8192 codes times the victim's windows over the frame
    # (0.1 s: the share's standard deviation about 0.0015)
    point = dict(scheme="hopping", hop_periods=16, hop_step_cycles=3, hop_dwell=64,
                 t_int_s=0.1)
    for seed in range(10, 14):
        share, starts = _landing_share(point, 2, seed)
        expected = 8192 * len(starts) / (0.1 / TDC_LSB_S)
        assert abs(share - expected) < 0.006, (share, expected)
    # and the victim's mean period is the mean of its hop set (1 s: 9800 dwells, the mean's
    # standard deviation 0.14 cycles)
    starts = Camera.draw(check_point(point), np.random.default_rng(9),
                         victim=True).bursts(0.0, 1.0 / TDC_LSB_S)
    mean = np.diff(starts).mean() / LSB_PER_CYCLE
    assert abs(mean - (80 + 3 * 15 / 2)) < 0.6, mean
    # which is the period the energy a pulse is worked out from
    assert mean_period_cycles(check_point(point)) == 80 + 3 * 15 / 2


def test_prf_hopping_dwells_on_one_period_from_its_set():
    point = check_point(dict(scheme="hopping", hop_periods=4, hop_step_cycles=5, hop_dwell=50))
    starts = Camera.draw(point, np.random.default_rng(3), victim=True).bursts(0.0, 1e7)
    periods = np.diff(starts) / LSB_PER_CYCLE
    assert set(np.round(periods).astype(int)) <= {80, 85, 90, 95}
    changes = np.flatnonzero(np.diff(periods) != 0)
    assert np.all(np.diff(changes) % 50 == 0)


def test_fliss_windows_follow_the_mean_period():
    point = check_point(dict(scheme="fliss", length=6))
    for seed in (1, 2):
        starts = Camera.draw(point, np.random.default_rng(seed), victim=True).bursts(
            0.0, 0.01 / TDC_LSB_S)
        # mseq L = 6: each 63 pulses hold the delays 0 ... 62 once, 63 (80 + 31) cycles
        spans = starts[63:] - starts[:-63]
        assert np.all(spans == 63 * 111 * LSB_PER_CYCLE)
        assert abs(len(starts) - 0.01 * 80e6 / 111) <= 3
    assert mean_period_cycles(point) == 111


@pytest.mark.parametrize("chips, slots", [(4, 16), (5, 24), (3, 4)])
def test_golomb_code_correlates_to_a_peak_of_its_chips_and_sidelobes_of_one(chips, slots):
    rng = np.random.default_rng(chips)
    code = golomb_code(rng, chips, slots)
    differences = [abs(a - b) for a in code for b in code if a != b]
    assert len(differences) == len(set(differences)) * 2
    assert code.min() == 0 and code.max() < slots and len(set(code)) == chips
    # A noiseless echo: h counts at every chip after a time of flight tof
    h, tof, length = 7, 321, 2000
    raw = np.zeros(length + code.max() + 1, dtype=np.int64)
    raw[code + tof] = h
    result = correlate(raw, code, length)
    assert result[tof] == chips * h
    assert np.delete(result, tof).max() <= h


def test_golomb_code_refuses_too_few_slots():
    with pytest.raises(ValueError, match="slots"):
        golomb_code(np.random.default_rng(0), 5, 10)


@pytest.mark.parametrize("scheme", ["none", "hopping", "fliss", "code"])
def test_every_scheme_sends_the_same_echo_energy_a_frame(scheme):
    # No background, one camera: every photon is the echo's; one SPAD counts the first of a
    # pulse, so counts a pulse = 1 - exp(-mu), mu the detections a pulse
    point = dict(scheme=scheme, background_hz=0.0, frames=4, detections_per_frame=400.0)
    result = evaluate(point, np.random.SeedSequence(5))
    pulses = pulses_per_frame(check_point(point))
    mu = 400.0 / pulses
    expected = pulses * (1 - math.exp(-mu))
    measured = result["echo_counts_per_frame"]
    assert result["detections_per_pulse"] == pytest.approx(mu)
    assert abs(measured - expected) < 4 * math.sqrt(expected / 4) + 2, (measured, expected)


def test_the_echo_of_n_spads_meets_k_of_n_as_the_binomial_says():
    # A strong pulse, no background, a window wider than the pulse: a pulse fires the gate when
    # at least k of the n SPADs get a photon; the counts of a SPAD are Poisson(mu / n)
    point = dict(scheme="none", spads=4, coincidence=2, coincidence_window_ns=20.0,
                 period_cycles=8000, background_hz=0.0, detections_per_frame=300.0, frames=20)
    result = evaluate(point, np.random.SeedSequence(6))
    pulses = pulses_per_frame(check_point(point))
    p = 1 - math.exp(-300.0 / pulses / 4)
    expected = pulses * sum(math.comb(4, j) * p ** j * (1 - p) ** (4 - j) for j in range(2, 5))
    measured = result["echo_events_per_frame"]
    assert abs(measured - expected) < 4 * math.sqrt(expected / 20) + 0.5, (measured, expected)


@pytest.mark.parametrize("change, message", [
    (dict(coincidence=3, spads=2), "at most spads"),
    (dict(coincidence=2, spads=4, coincidence_window_ns=25.0), "dead time"),
    (dict(scheme="prf"), "scheme"),
    (dict(cameras=65), "cameras"),
    (dict(scheme="code", code_chips=6, code_slots=10), "slots"),
    (dict(scheme="code", period_cycles=40), "fit in a period"),
    (dict(gain=1), "Unknown point parameter"),
    (dict(multi_hit=True, keep="first"), "single-hit"),
    (dict(scheme="code", keep="first"), "single-hit"),
])
def test_bad_points_are_refused_in_one_line(change, message):
    with pytest.raises(ValueError, match=message) as error:
        check_point(change)
    assert "\n" not in str(error.value)


def test_parameters_document_every_default():
    assert set(check_point({})) == set(PARAMETERS)


def test_ambient_light_is_thinned_by_the_pdp_and_counted_through_the_dead_time():
    # spcm20a: PDP 0.35, 25 Hz dark counts, 35 ns non-paralysable dead time: a SPAD under a
    # Poisson rate r counts r / (1 + r tau)
    from fliss.sim.studies.schemes.frame import simulate_frame, window_codes
    from fliss.sim.scene import PRESETS
    point = check_point(dict(scheme="none", background_hz=1e7, detections_per_frame=0.0,
                             sensor_preset="spcm20a"))
    point.update(_tof_lsb=0.0, _detections_per_pulse=0.0)
    detector = PRESETS["spcm20a"]
    frame = simulate_frame(point, detector, np.random.default_rng(8))
    length = window_codes(point)
    span = (0.01 / TDC_LSB_S + length + 2.0 * length + 35e-9 / TDC_LSB_S) * TDC_LSB_S
    rate = 1e7 * 0.35 + 25.0
    expected = rate / (1 + rate * 35e-9) * span
    assert abs(frame.counts[1] - expected) < 4 * math.sqrt(expected), (frame.counts[1], expected)


@pytest.mark.parametrize("keep", ["last", "first"])
def test_the_single_hit_tdc_keeps_the_echo_as_poisson_statistics_say(keep):
    # One camera, ambient b: a counted echo photon at the time of flight t is the last of its
    # window when no ambient photon comes after its dead time d, before the window's end W:
    # exp(-b (W - t - d)); it is the first when no ambient photon was counted in the window
    # before it: one within d before it would have blinded the SPAD (the echo photon is then
    # not counted at all), so exp(-b (t - d))
    b, tof = 1e6, 2 * 4.0 / 299_792_458
    point = dict(scheme="none", background_hz=b, frames=20, keep=keep)
    result = evaluate(point, np.random.SeedSequence(9))
    kept = result["echo_events_per_frame"] / result["echo_counts_per_frame"]
    window = 8192 * TDC_LSB_S
    expected = math.exp(-b * (window - tof - 20e-9)) if keep == "last" else \
        math.exp(-b * (tof - 20e-9))
    counts = result["echo_counts_per_frame"] * 20
    assert abs(kept - expected) < 4 * math.sqrt(expected * (1 - expected) / counts), \
        (kept, expected)


@pytest.mark.parametrize("paralysable", [False, True])
def test_afterpulses_of_one_spad_follow_their_geometric_series(paralysable):
    # Isolated primaries: an avalanche releases an afterpulse with probability p after an
    # exponential delay of mean tau. Non-paralysable, it counts (and can afterpulse again) only
    # after the dead time d: q = p exp(-d / tau) a generation, q / (1 - q) counted a primary.
    # Paralysable, every afterpulse is an avalanche that can afterpulse, counted when d after
    # its parent: exp(-d / tau) p / (1 - p).
    p, tau, dead = 0.2, 40e-9, 20e-9
    detector = Detector(dead_time_s=dead, paralysable=paralysable, afterpulse_probability=p,
                        afterpulse_s=(tau,))
    primaries = 20000
    times = np.arange(primaries) * (10e-6 / TDC_LSB_S)
    rng = np.random.default_rng(11)
    counted, sources = avalanches(times, np.zeros(primaries, dtype=np.int16),
                                  np.zeros(primaries, dtype=np.int64), detector, 1, rng, 2)
    assert (sources == 0).sum() == primaries
    q = p * math.exp(-dead / tau)
    expected = (math.exp(-dead / tau) * p / (1 - p) if paralysable else q / (1 - q)) * primaries
    measured = (sources == 2).sum()
    assert abs(measured - expected) < 4 * math.sqrt(expected), (measured, expected)


def test_the_diffusion_tail_delays_its_share_of_the_pulsed_photons():
    detector = Detector(tail_fraction=0.3, tail_s=2e-9)
    primaries = 20000
    times = np.arange(primaries) * (10e-6 / TDC_LSB_S)
    counted, sources = avalanches(times, np.zeros(primaries, dtype=np.int16),
                                  np.zeros(primaries, dtype=np.int64), detector, 1,
                                  np.random.default_rng(12), 2)
    late = (counted - times) * TDC_LSB_S
    # a share 0.3 late by an exponential of mean 2 ns: mean 0.6 ns, and 0.3 exp(-1) beyond 2 ns
    assert abs(late.mean() - 0.6e-9) < 4 * math.sqrt(0.3 * 2 * 4e-18 - 0.36e-18) / \
        math.sqrt(primaries)
    assert abs((late > 2e-9).mean() - 0.3 * math.exp(-1)) < 0.01
