"""Density-control windows survive shortening (`GaussianConfig.density_windows`): at 100 and 200
steps the window still densifies at least MIN_DENSIFICATIONS times and opacity resets stay far
enough apart for the Gaussians to recover; at the presets' own lengths the floors do not bind (the
paper's and the mini suite's runs are unchanged)."""

from __future__ import annotations

import pytest

from olatbench.methods.gaussian_config import MIN_DENSIFICATIONS, GaussianConfig
from olatbench.methods.registry import get_spec

METHODS = ("3dgs", "gs3", "ssdgs")


def _config(method: str, preset: str | None, **overrides):
    return get_spec(method).resolve_config(preset, **overrides)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("preset", [None, "nrhints", "gs3", "sssgs", "mini"])
@pytest.mark.parametrize("iterations", [100, 200])
def test_shortened_runs_keep_room_to_densify_and_space_between_resets(method, preset, iterations):
    config = _config(method, preset, iterations=iterations)
    windows = config.density_windows()
    densifications = [
        step
        for step in range(1, iterations + 1)
        if windows.densify_from < step < windows.densify_until and step % windows.interval == 0
    ]
    assert len(densifications) >= MIN_DENSIFICATIONS - 1, windows  # the window's ends are open
    # a reset opacity (0.01) needs ~ln(99) / opacity_lr Adam steps to climb back to 0.5: resets stay
    # 3 such apart
    assert windows.opacity_reset_interval >= 3 * 4.59 / config.opacity_lr
    # 200 steps of 3DGS's own 100K windows reset every 6 steps before the floor (issue #46)
    assert windows.opacity_reset_interval > iterations  # so no reset at all in runs this short


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("preset", [None, "nrhints", "gs3", "sssgs", "mini"])
def test_floors_do_not_bind_at_the_presets_own_lengths(method, preset):
    config = _config(method, preset)
    windows = config.density_windows()
    assert (
        windows.densify_from,
        windows.densify_until,
        windows.interval,
        windows.opacity_reset_interval,
    ) == (
        max(1, config.steps(config.densify_from)),
        max(1, config.steps(config.densify_until)),
        config.densify_interval,
        max(1, config.steps(config.opacity_reset_interval)),
    )


def test_floor_of_the_interval_and_of_resets_in_closed_form():
    # window (17, 500], reset 100 -> floor
    config = GaussianConfig(iterations=1_000, reference_iterations=30_000)
    windows = config.density_windows()
    assert (windows.densify_from, windows.densify_until) == (17, 500)
    assert windows.interval == (500 - 17) // MIN_DENSIFICATIONS == 48
    assert windows.opacity_reset_interval == 276  # ceil(3 ln 99 / 0.05)
    # never
    assert (
        GaussianConfig(opacity_lr=0.0, iterations=50).density_windows().opacity_reset_interval == 51
    )
    # a run at its reference length keeps the windows it was given, however short
    # (no scaling, no floor)
    given = GaussianConfig(
        iterations=60, reference_iterations=60, opacity_reset_interval=10
    ).density_windows()
    assert given.opacity_reset_interval == 10 and given.interval == 100


def test_the_densifier_runs_the_floored_windows():
    import numpy as np

    from olatbench.methods.training import make_densifier

    # the run: a reset every 6 steps before
    config = _config("3dgs", "nrhints", iterations=200)
    windows = config.density_windows()
    densify = make_densifier(config, np.zeros(3), seed=0).config
    assert (
        densify.densify_from,
        densify.densify_until,
        densify.densify_interval,
        densify.opacity_reset_interval,
    ) == (
        windows.densify_from,
        windows.densify_until,
        windows.interval,
        windows.opacity_reset_interval,
    )
    assert densify.opacity_reset_interval > 200 and densify.densify_interval < 100
