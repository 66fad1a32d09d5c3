"""Closed-loop steps with the detector's effects resolve a few photons in plain Python
(fliss.sim.scene.few_avalanches); numpy's path (Avalanches) gives the same run, bit for bit, on
the same draws: one pixel, and pixel arrays with crosstalk (column and per-pixel sensors)."""

import numpy as np
import pytest

from fliss.sim.scene import COUNTERS, Detector, PixelArray, Scene, simulation_for


def _runs(scene, steps):
    """Events and counters of the same run stepped with plain Python for a few photons, and
    with numpy for every step."""
    starts = 100 + np.cumsum(np.random.default_rng(7).integers(20, 121, 3 * steps + 1))
    runs = []
    for few_photons in (None, -1):
        simulation = simulation_for(scene, seed=4, chunk_cycles=64, external_starts=True)
        if few_photons is not None:
            simulation.few_photons = few_photons
        simulation.feed(starts)
        events = [simulation.step(1 + index % 3).events for index in range(steps)]
        counts = getattr(simulation, "pixel_counts", simulation.counts)
        runs.append((np.concatenate(events), counts.copy()))
    return runs


@pytest.mark.parametrize("paralysable", [False, True])
@pytest.mark.parametrize("keep", ["last", "first"])
def test_few_photons_through_the_effects_give_what_numpy_gives(paralysable, keep):
    # Strong afterpulsing with two exponentials (chains of children, some past the step's
    # boundary, carried), a diffusion tail, dark counts and a PDP; fed starts 20 to 120
    # cycles apart, one to three laser cycles a step, as the virtual boards step it
    detector = Detector(pdp=0.6, dark_count_hz=3e5, paralysable=paralysable, dead_time_s=20e-9,
                        tail_fraction=0.3, tail_s=2e-9, afterpulse_probability=0.3,
                        afterpulse_s=(15e-9, 300e-9), afterpulse_weights=(0.6, 0.4))
    scene = Scene(detections_per_pulse=0.5, background_hz=2e6, detector=detector, keep=keep)
    steps = 3000
    runs = _runs(scene, steps)
    (events, counts), (reference, reference_counts) = runs
    # Afterpulses counted and carried over: the plain path met what it must reproduce
    assert reference_counts[-1, 0] > 200 and len(reference) > steps // 2
    assert np.array_equal(events, reference)
    assert np.array_equal(counts, reference_counts)


@pytest.mark.parametrize("sensor", ["column", "per_pixel"])
@pytest.mark.parametrize("paralysable", [False, True])
def test_few_photons_of_an_array_with_crosstalk_give_what_numpy_gives(sensor, paralysable):
    # Strong crosstalk (orthogonal and diagonal: a 3 x 4 array of the per-pixel sensor) and
    # afterpulsing: children in other pixels, collisions on the column
    detector = Detector(pdp=0.6, dark_count_hz=3e5, paralysable=paralysable, dead_time_s=20e-9,
                        tail_fraction=0.3, tail_s=2e-9, afterpulse_probability=0.2,
                        afterpulse_s=(15e-9, 300e-9), crosstalk_orthogonal=0.15,
                        crosstalk_diagonal=0.05)
    columns = 1 if sensor == "column" else 3
    pixels = PixelArray(distance_m=np.full(12, 4.0), sensor=sensor, columns=columns)
    scene = Scene(detections_per_pulse=0.6, background_hz=1e6, pixels=pixels,
                  detector=detector)
    steps = 1500
    (events, counts), (reference, reference_counts) = _runs(scene, steps)
    generated = reference_counts[:, :, COUNTERS.index("generated")].sum(axis=0)
    assert generated[-1] > 100 and generated[-2] > 100, generated and len(reference) > steps // 2
    assert np.array_equal(events, reference)
    assert np.array_equal(counts, reference_counts)
