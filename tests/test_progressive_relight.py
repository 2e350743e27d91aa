"""The viewer's progressive environment relight (`olatbench.bench.progressive`): the refinement
order spreads every prefix over the samples, each intermediate image is the average of its samples'
images, and the image after all batches is the `Relighter`'s image of the same samples."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_relight import gaussian

from olatbench.bench.progressive import ProgressiveRelight, refinement_order
from olatbench.datasets.lighting import SampledLights, environment_lighting


def test_the_refinement_order_is_a_permutation_whose_prefixes_spread_over_the_samples():
    order = refinement_order(16)
    assert sorted(order.tolist()) == list(range(16))
    # every 4th stratum
    assert order[:2].tolist() == [0, 8] and sorted(order[:4].tolist()) == [0, 4, 8, 12]
    assert sorted(order[:8].tolist()) == list(range(0, 16, 2))
    for count in (1, 5, 6, 64, 100):
        assert sorted(refinement_order(count).tolist()) == list(range(count))
    with pytest.raises(ValueError, match="at least one light"):
        refinement_order(0)


@pytest.mark.parametrize("name", ["ssdgs", "gs3", "3dgs"])
def test_after_all_batches_a_progressive_relight_is_the_relighters_image_of_the_same_samples(name):
    relighter, views = gaussian(name)
    camera = views.cameras[0]
    samples = 16
    lights = environment_lighting("studio", samples, seed=3, rotation=30.0, exposure=-1.0).sample(
        relighter.reference.up
    )
    relight = ProgressiveRelight(relighter, camera, lights)
    # a light-blind method: one render of the summed weights
    expected_total = samples if name != "3dgs" else 1
    assert relight.total == expected_total
    estimates = []
    for batch in (4, 8, 8):  # the viewer's preview, then passes of 8 (the last one short)
        rendered = relight.advance(batch)
        assert rendered == min(batch, expected_total - (relight.done - rendered))
        estimates.append(relight.estimate())
    assert relight.finished and relight.done == expected_total
    np.testing.assert_allclose(
        estimates[-1], relighter.linear(camera, lights), rtol=1e-5, atol=1e-6
    )
    if name != "3dgs":  # four samples of sixteen: an estimate, not the image
        assert np.abs(estimates[0] - estimates[-1]).max() > 1e-3


def test_an_intermediate_image_is_the_average_of_its_samples_images():
    """After n of K samples the image is the mean of the n one-sample estimates of the whole map
    (each sample's light K times as bright), background included once."""
    relighter, views = gaussian("ssdgs", background=1.0)
    camera = views.cameras[2]
    lights = environment_lighting("sky", 8, seed=1).sample(relighter.reference.up)
    relight = ProgressiveRelight(relighter, camera, lights)
    relight.advance(3)
    first = [lights.directions[i] for i in refinement_order(8)[:3]]
    one_sample = [
        relighter.linear(
            camera,
            SampledLights(
                directions=(dataclasses.replace(light, irradiance=8.0 * light.irradiance),)
            ),
        )
        for light in first
    ]
    np.testing.assert_allclose(
        relight.estimate(), np.mean(one_sample, axis=0), rtol=1e-5, atol=1e-6
    )


def test_advance_stops_when_asked_and_an_estimate_needs_a_sample():
    relighter, views = gaussian("gs3")
    lights = environment_lighting("furnace", 8).sample(relighter.reference.up)
    relight = ProgressiveRelight(relighter, views.cameras[0], lights)
    with pytest.raises(ValueError, match="advance first"):
        relight.estimate()
    asked = []
    assert relight.advance(8, stop=lambda: asked.append(1) or len(asked) > 3) == 3
    assert relight.done == 3 and not relight.finished
