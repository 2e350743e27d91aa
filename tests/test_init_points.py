"""Initialisation from a point cloud (`olatbench.bench.init_points`): a scene folder's
``points3d.ply`` or ``run --init-points FILE``, for the methods with the ``init_points`` capability
(ssdgs, gs3, 3dgs)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
import test_runner_support as support
from click.testing import CliRunner

from olatbench.bench.execute import run_job
from olatbench.bench.init_points import load_init_points
from olatbench.bench.plan import load_method_class, make_plan
from olatbench.bench.restore import restore
from olatbench.bench.views import frame_views
from olatbench.cli import main
from olatbench.datasets import load_scene, suites
from olatbench.gaussians.ply import write_ply_points


@pytest.fixture(autouse=True)
def _isolated(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setitem(suites.SUITES, "tiny", support.tiny_suite(scenes=("Alpha",)))


def cloud(count: int = 123, seed: int = 7) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-0.8, 0.8, (count, 3)).astype(np.float32)


def plan(tmp_path: Path, method: str = "3dgs", **options):
    data = tmp_path / "data"
    if not data.exists():
        support.write_tiny_data(data, scenes=("Alpha",))
    return make_plan(
        method,
        "tiny",
        tmp_path / "runs",
        variants=["mini"],
        iterations=2,
        data_root=data,
        progress=False,
        **options,
    )[0]


@pytest.mark.parametrize("method", ["ssdgs", "gs3", "3dgs"])
def test_the_initial_centres_are_the_files_points(tmp_path, method):
    points = cloud()
    write_ply_points(tmp_path / "cloud.ply", points, np.full((len(points), 3), 0.5, np.float32))
    job = plan(tmp_path, method, init_points=tmp_path / "cloud.ply")
    scene = load_scene(job.scene_path, format=job.scene_format)
    views = dataclasses.replace(
        frame_views(scene.split(job.train_split), job),
        points=load_init_points(job.init_points, job.init_points_digest),
    )
    cls = load_method_class(job)
    instance = cls(cls.resolve_config(None, **job.config))
    instance.setup(views, "cpu", job.seed)
    # a suite of one's own: the method works in the fitted canonical frame
    assert not views.frame.is_identity
    centres = instance.model.means.detach().numpy()
    # the points, moved into the frame with the cameras
    np.testing.assert_allclose(centres, views.frame.points(points), rtol=0, atol=1e-5)
    np.testing.assert_allclose(views.frame.inverse().points(centres), points, rtol=0, atol=1e-5)
    assert job.config["num_init_gaussians"] != len(points)


def test_a_scene_folders_points3d_ply_is_used_and_enters_the_job_id(tmp_path):
    without = plan(tmp_path)
    assert without.init_points == "" and without.init_points_digest is None
    # ids of jobs without a point cloud are unchanged
    assert "init_points" not in without.identity()
    points = cloud()
    write_ply_points(tmp_path / "data" / "Alpha" / "points3d.ply", points)
    job = plan(tmp_path)
    assert Path(job.init_points) == (tmp_path / "data" / "Alpha" / "points3d.ply").resolve()
    assert job.identity()["init_points"] == job.init_points_digest and job.id != without.id
    # the scene's own cloud: the scene's default, no label of its own
    assert job.variant == without.variant
    outcome = run_job(job, progress=False)
    assert outcome.status == "done", (Path(job.folder) / "error.txt").read_text()
    log = (Path(job.folder) / "log.txt").read_text()
    assert f"starting from the {len(points)} points of" in log
    method, _ = restore(job.folder)  # the checkpoint is restored without the point cloud
    assert method.model.num_gaussians == len(points)  # two steps: no densification yet
    write_ply_points(tmp_path / "data" / "Alpha" / "points3d.ply", cloud(seed=8))
    assert plan(tmp_path).id != job.id


def test_cli_init_points_names_the_file_in_the_label_and_refuses_methods_that_cannot(
    tmp_path, monkeypatch
):
    data = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",))
    write_ply_points(tmp_path / "sparse.ply", cloud())
    monkeypatch.chdir(tmp_path)
    args = [
        "run",
        "-s",
        "tiny",
        "--data-root",
        str(data),
        "--init-points",
        "sparse.ply",
        "--dry-run",
        "--json",
    ]
    result = CliRunner().invoke(main, [args[0], "-m", "3dgs", *args[1:]])
    assert result.exit_code == 0, result.output
    (job,) = json.loads(result.output)
    assert job["variant"] == "default~init_points=sparse"
    refused = CliRunner().invoke(main, [args[0], "-m", "ssdgs-official", *args[1:]])
    assert refused.exit_code == 2 and "cannot start from a point cloud" in refused.output, (
        refused.output
    )
