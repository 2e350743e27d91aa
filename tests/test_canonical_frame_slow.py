"""Done-when of #46's frame part: a scene and a similarity-transformed copy of it (scale 10, a
rotation, a translation of ~60 units: 15 camera distances, 60 object radii; tests/moved_scenes.py)
give ssdgs, gs3 and 3dgs the same test PSNR within seed noise (3 seeds, short runs), through
``olatbench run --data``; every run must have trained (no health warning), so that two ruined runs
cannot pass by scoring the same."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from moved_scenes import move_scene

from olatbench.bench.health import read_warnings
from olatbench.bench.results import read_results
from olatbench.cli import main

SEEDS = 3
# CPU-sized: 80 steps of the mini preset with fewer Gaussians and a 32² light view (18 jobs)
SETTINGS = {"ssdgs": ("shadow_resolution=32",), "gs3": ("shadow_resolution=32",), "3dgs": ()}
SMALL = ("num_init_gaussians=500", "max_gaussians=1000")


@pytest.fixture(scope="module")
def scenes(tmp_path_factory) -> tuple[Path, Path]:
    """A 32² diffuse_shadow scene rendered with Mitsuba (its object off the world origin), 8
    training and 4 test frames, and its moved copy."""
    pytest.importorskip("mitsuba")
    root = tmp_path_factory.mktemp("frames")
    result = CliRunner().invoke(
        main,
        [
            "datasets",
            "synth",
            "--recipe",
            "diffuse_shadow",
            "-o",
            str(root / "scene"),
            "--resolution",
            "32",
            "--spp",
            "8",
            "--train",
            "8",
            "--test",
            "4",
            "--no-geometry",
            "-q",
        ],
    )
    assert result.exit_code == 0, result.output
    return root / "scene", move_scene(root / "scene", root / "moved")


@pytest.mark.slow
@pytest.mark.parametrize("method", ["ssdgs", "gs3", "3dgs"])
def test_a_moved_scene_scores_the_same_within_seed_noise(method, scenes, tmp_path):
    runs = tmp_path / "runs"
    settings = [argument for value in (*SMALL, *SETTINGS[method]) for argument in ("--set", value)]
    result = CliRunner().invoke(
        main,
        [
            "run",
            "-m",
            method,
            "--data",
            str(scenes[0]),
            "--data",
            str(scenes[1]),
            "--variant",
            "mini",
            "--iterations",
            "80",
            "--seeds",
            str(SEEDS),
            *settings,
            "-o",
            str(runs),
            "-q",
        ],
    )
    assert result.exit_code == 0, result.output
    psnr = {}
    for path in runs.rglob("results.json"):
        results = read_results(path)
        # a run that learned nothing scores the same on both scenes: each must have trained (no
        # warning of a collapse or of a training PSNR below the background-only image's,
        # olatbench.bench.health)
        assert read_warnings(path.parent) == [], (method, path.parent)
        psnr.setdefault(results["job"]["scene"], []).append(
            results["metrics"]["test"]["mean"]["psnr"]
        )
    original, moved = np.array(psnr["scene"]), np.array(psnr["moved"])
    assert len(original) == len(moved) == SEEDS
    noise = max(original.std(ddof=1), moved.std(ddof=1))
    assert abs(original.mean() - moved.mean()) <= 2.0 * noise + 0.01, (method, original, moved)
