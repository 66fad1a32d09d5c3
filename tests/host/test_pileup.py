"""Pile-up correction (:mod:`fliss.analysis.pileup`, ``fliss analyze --pileup``) against the
law the photons were drawn from: Poisson arrivals per bin, one photon kept per laser cycle."""

import json
import math

import numpy as np
import pytest

from fliss.analysis.pileup import PileupError, coates
from fliss.hdl.registers import defaults
from fliss.host.cli import main
from fliss.host.fileformat import CaptureWriter
from fliss.host.stream import EventBatch, HistogramFrame
from fliss.protocol.events import EVENT_DTYPE

from imager_frames import identity


BINS = 64
CYCLES = 200_000


def _laws():
    i = np.arange(BINS)
    flat_pulse = np.full(BINS, 0.02)
    flat_pulse += 0.6 * np.exp(-0.5 * ((i - 30) / 2.0) ** 2)       # 3 photons a pulse
    exponential = 0.4 * np.exp(-i / 12.0)                           # 3.4 photons a cycle
    return {"flat+pulse": flat_pulse, "exponential": exponential}


def _kept(rates, cycles, keep, rng):
    """Draw Poisson photons in every bin of every cycle, keep the first or the last bin that
    has one; the histogram of the kept bins."""
    hit = rng.poisson(rates, (cycles, len(rates))) > 0
    any_hit = hit.any(axis=1)
    index = np.argmax(hit, axis=1) if keep == "first" else \
        len(rates) - 1 - np.argmax(hit[:, ::-1], axis=1)
    return np.bincount(index[any_hit], minlength=len(rates))


@pytest.mark.parametrize("keep", ["first", "last"])
@pytest.mark.parametrize("law", ["flat+pulse", "exponential"])
def test_the_correction_recovers_the_rate_of_every_bin(law, keep):
    rates = _laws()[law]
    histogram = _kept(rates, CYCLES, keep, np.random.default_rng(7))
    result = coates(histogram, CYCLES, keep)
    # The binomial error of each bin's estimate, with its cycles at risk and its true rate
    p = -np.expm1(-rates)
    sigma = np.sqrt(p / ((1 - p) * result.at_risk))
    z = (result.rate - rates) / sigma
    # Within the binomial error, bin by bin, and the errors as wide as they say (chi-square of
    # 64 bins: mean 1, standard deviation 0.18)
    assert np.abs(z).max() < 4.5, z
    assert 0.5 < np.mean(z ** 2) < 1.6, np.mean(z ** 2)
    # ... where the raw histogram is far off: it piles up towards the kept end
    raw = histogram / CYCLES
    assert np.abs((raw - rates) / sigma).max() > 50


@pytest.mark.parametrize("law", ["flat+pulse", "exponential"])
def test_the_last_photon_behind_a_dead_time_recovers_the_rate_of_every_bin(law):
    # A non-paralysable SPAD blind for 6 bins after each avalanche, the TDC keeping the last:
    # drawn cycle by cycle, bin after bin (a photon in a bin while ready is an avalanche)
    rates, dead = _laws()[law], 6
    rng = np.random.default_rng(8)
    photons = rng.poisson(rates, (CYCLES, BINS)) > 0
    ready, last = np.zeros(CYCLES, dtype=np.int64), np.full(CYCLES, -1)
    for index in range(BINS):
        fired = photons[:, index] & (ready <= index)
        last[fired] = index
        ready[fired] = index + dead
    histogram = np.bincount(last[last >= 0], minlength=BINS)
    result = coates(histogram, CYCLES, "last", dead)
    p = -np.expm1(-rates)
    sigma = np.sqrt(p / ((1 - p) * result.at_risk))
    z = (result.rate - rates) / sigma
    assert np.abs(z).max() < 4.5, z
    assert 0.5 < np.mean(z ** 2) < 1.6, np.mean(z ** 2)
    # ... where the counterpart without the dead time is far off
    plain = coates(histogram, CYCLES, "last")
    assert np.abs((plain.rate - rates) / sigma).max() > 50


def test_the_correction_refuses_what_it_cannot_measure():
    with pytest.raises(PileupError, match="more than its 10 laser cycles"):
        coates([5, 6], 10)
    with pytest.raises(PileupError, match=r"^bin 1: every laser cycle left there \(6\) "
                                          r"recorded it"):
        coates([4, 6, 0], 10, "first")
    with pytest.raises(PileupError, match="number of laser cycles must be a whole number"):
        coates([1, 2], 0)
    with pytest.raises(PileupError, match="keeps the 'first' or the 'last'"):
        coates([1, 2], 10, "middle")
    with pytest.raises(PileupError, match=r"^bin 0: every laser cycle left there \(6\)"):
        coates([6, 4, 0], 10, "last")
    with pytest.raises(PileupError, match="whole numbers, not negative"):
        coates([1, -2], 10)


# fliss analyze --pileup on a raw capture of an echo piled up

ECHO_S = 100e-9
SIGMA_S = 2.1e-9 / (2 * math.sqrt(2 * math.log(2)))
LSB_S = 50e-12


def _raw_events(cycles, keep, rng, *, echo=3.0, background_hz=1e6):
    """Each cycle's photons (echo: Poisson ``echo``, Gaussian of the paper's FWHM at
    ``ECHO_S``; background over the 409.6 ns window), the first or the last kept."""
    window_s = 8192 * LSB_S
    signal = rng.poisson(echo, cycles)
    ambient = rng.poisson(background_hz * window_s, cycles)
    owner = np.concatenate((np.repeat(np.arange(cycles), signal),
                            np.repeat(np.arange(cycles), ambient)))
    times = np.concatenate((rng.normal(ECHO_S, SIGMA_S, signal.sum()),
                            rng.uniform(0, window_s, ambient.sum())))
    inside = (times >= 0) & (times < window_s)
    owner, codes = owner[inside], np.floor(times[inside] / LSB_S).astype(np.int64)
    kept = np.full(cycles, -1 if keep == "last" else 1 << 20)
    (np.maximum if keep == "last" else np.minimum).at(kept, owner, codes)
    cycle = np.flatnonzero((kept >= 0) & (kept < 8192))
    events = np.zeros(len(cycle), dtype=EVENT_DTYPE)
    events["timestamp"], events["pulse"] = kept[cycle], cycle
    return events


def _raw_file(path, events, cycles, *, drops=0):
    status = {"running": 0, "dropped_overrun": 0, "dropped_gate": 0}
    with CaptureWriter(str(path), mode="raw", identity=identity(),
                       configuration=defaults(80_000_000)) as writer:
        for start in range(0, len(events), 10_000):
            writer.add_events(EventBatch(events[start:start + 10_000], float(start)))
        writer.set_counters("board_start", dict(status, pulses=0, dropped_fifo=0))
        writer.set_counters("board_end", dict(status, pulses=cycles, dropped_fifo=drops))
        writer.set_counters("link", {"missing_packets": 0, "dropped_frames": 0})
    return str(path)


def _tof(capsys, argv):
    assert main(["analyze", "--json", *argv]) == 0
    record = json.loads(capsys.readouterr().out)[0]
    return record, max(record["peaks"], key=lambda peak: peak["height"])["tof_s"]


@pytest.mark.parametrize("keep", ["first", "last"])
def test_fliss_analyze_corrects_the_depth_of_a_piled_up_echo(tmp_path, capsys, keep):
    cycles = 100_000
    events = _raw_events(cycles, keep, np.random.default_rng(11))
    path = _raw_file(tmp_path / "raw.h5", events, cycles)
    _, raw_tof = _tof(capsys, [path])
    dead = ["--dead-time", "0ns"] if keep == "last" else []
    record, corrected_tof = _tof(capsys, [path, "--pileup", keep, *dead])
    assert record["pileup"] == {"keep": keep, "cycles": cycles,
                                "dead_time_s": 0.0 if keep == "last" else None}
    assert len(record["peaks"]) == 1            # the echo, and no ghost of the corrected noise
    # Three photons a pulse: the kept one is the earliest (latest) of them, some 0.85 sigma
    # (0.76 ns) off the echo's centre; the corrected histogram has the echo where it is
    shift = raw_tof - ECHO_S
    assert (shift < -0.3e-9) if keep == "first" else (shift > 0.3e-9), shift
    assert abs(corrected_tof - ECHO_S) < 0.1e-9, corrected_tof - ECHO_S


def test_fliss_analyze_corrects_the_paper_sensors_pile_up_with_its_dead_time(tmp_path,
                                                                            capsys):
    # The scene simulator's pixel as on the virtual boards: the TDC keeps the last photon, the
    # SPAD is blind 20 ns after an avalanche (longer than the 2.1 ns pulse: of an echo of 3
    # detections a pulse it detects the first), 100 kHz of ambient light; 4 m: 26.685 ns
    from fliss.sim.scene import Detector, Scene, acquire, time_of_flight
    scene = Scene(distance_m=4.0, detections_per_pulse=3.0, keep="last",
                  detector=Detector(dead_time_s=20e-9))
    run = acquire(scene, 0.05, 1, seed=2, keep_events=True)
    cycles = int(run.cycles[0])
    path = _raw_file(tmp_path / "paper.h5", run.events[0], cycles)
    tof_s = time_of_flight(4.0)
    _, raw_tof = _tof(capsys, [path])
    _, blind_tof = _tof(capsys, [path, "--pileup", "last", "--dead-time", "0ns"])
    record, corrected_tof = _tof(capsys, [path, "--pileup", "last", "--dead-time", "20ns"])
    assert record["pileup"] == {"keep": "last", "cycles": cycles, "dead_time_s": 20e-9}
    assert raw_tof - tof_s < -0.3e-9 and blind_tof - tof_s < -0.6e-9
    assert abs(corrected_tof - tof_s) < 0.1e-9, corrected_tof - tof_s


@pytest.mark.parametrize("keep", ["first", "last"])
def test_piled_up_background_makes_no_peak_once_corrected(keep):
    # 5 MHz of ambient light, two photons a window: the recorded background is tilted (keep
    # the first: falling; the last: rising), and the Poisson test of a flat background finds
    # peaks all over it; corrected, the background is flat and background alone passes the test
    # in 1e-3 of histograms
    from fliss.analysis.peaks import find_peaks
    from fliss.analysis.pileup import corrected_peaks
    raw = corrected = 0
    for seed in range(10):
        events = _raw_events(20_000, keep, np.random.default_rng(seed), echo=0.0,
                             background_hz=5e6)
        histogram = np.bincount(events["timestamp"], minlength=8192)
        raw += len(find_peaks(histogram, bin_s=LSB_S))
        corrected += len(corrected_peaks(histogram, 20_000, keep, bin_s=LSB_S)[1])
    assert raw > 100 and corrected == 0


def test_fliss_analyze_refuses_the_correction_where_it_cannot_apply(tmp_path, capsys):
    events = _raw_events(2000, "last", np.random.default_rng(1), echo=0.1)
    lossy = _raw_file(tmp_path / "lossy.h5", events, 2000, drops=3)
    with CaptureWriter(str(tmp_path / "hist.h5"), mode="histogram", identity=identity(),
                       configuration=dict(defaults(80_000_000), bin_shift=1)) as writer:
        row = np.bincount(events["timestamp"] >> 1, minlength=4096).astype(np.uint32)
        writer.add_histogram(HistogramFrame(0, 1, row, True, 0, 0.0))
    histogram = str(tmp_path / "hist.h5")
    for argv, message in (
            ([histogram, "--pileup", "first"],
             f"--pileup first: the number of laser cycles of {histogram}'s histograms is not "
             f"known (histogram captures do not record it): give --cycles N"),
            ([histogram, "--cycles", "2000"], "--cycles 2000 applies with --pileup only"),
            ([histogram, "--dead-time", "20ns"], "--dead-time 20ns applies with --pileup only"),
            ([histogram, "--pileup", "first", "--cycles", "2000", "--dead-time", "20ns"],
             "--dead-time 20ns applies with --pileup last: the first photon of a cycle does "
             "not depend on it"),
            ([histogram, "--pileup", "last", "--cycles", "2000"],
             "--pileup last needs the SPAD's --dead-time: it decides which photon can be the "
             "last (20ns on the virtual and model boards by default; 0ns if the SPAD detects "
             "every photon)"),
            ([lossy, "--pileup", "first"],
             f"--pileup first: {lossy} lost events on their way (dropped_fifo 3): the cycles "
             f"they were kept in would count as empty"),
            ([histogram, "--pileup", "first", "--cycles", "100"],
             f"--pileup first: {histogram}: the histogram holds {len(events)} counts, more "
             f"than its 100 laser cycles: a single-hit TDC records one photon a cycle at most "
             f"(the cycle count is not this histogram's)")):
        assert main(["analyze", *argv]) == 1
        assert capsys.readouterr().err == f"fliss: error: {message}\n"
    assert main(["analyze", histogram, "--pileup", "last", "--cycles", "2000",
                 "--dead-time", "20ns"]) == 0
    assert "pile-up corrected: last photon, dead time 20 ns, 2000 laser cycles" in \
        capsys.readouterr().out


@pytest.mark.parametrize("make", ["image", "depth"])
def test_pileup_of_pixels_that_share_a_tdc_is_refused(tmp_path, capsys, make):
    from format_captures import depth_capture, image_capture

    path = tmp_path / f"{make}.h5"
    (image_capture if make == "image" else depth_capture)(path)
    assert main(["analyze", str(path), "--pileup", "first", "--cycles", "1000"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("fliss: error: --pileup applies to ") and err.count("\n") == 1
    assert f"{path} is an {make} capture" in err or f"{path} is a {make} capture" in err
    assert "share the sensor's TDC" in err
