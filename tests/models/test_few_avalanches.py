"""Closed-loop steps of one pixel with the detector's effects resolve a few photons in plain
Python (fliss.sim.scene.few_avalanches); numpy's path (Avalanches) gives the same run, bit for
bit, on the same draws."""

import numpy as np
import pytest

from fliss.sim.scene import Detector, Scene, simulation_for


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
    starts = 100 + np.cumsum(np.random.default_rng(7).integers(20, 121, 3 * steps + 1))
    runs = []
    for few_photons in (None, -1):
        simulation = simulation_for(scene, seed=4, chunk_cycles=64, external_starts=True)
        if few_photons is not None:
            simulation.few_photons = few_photons
        simulation.feed(starts)
        events = [simulation.step(1 + index % 3).events for index in range(steps)]
        runs.append((np.concatenate(events), simulation.counts.copy()))
    (events, counts), (reference, reference_counts) = runs
    # Afterpulses counted and carried over: the plain path met what it must reproduce
    assert reference_counts[-1, 0] > 200 and len(reference) > steps // 2
    assert np.array_equal(events, reference)
    assert np.array_equal(counts, reference_counts)
