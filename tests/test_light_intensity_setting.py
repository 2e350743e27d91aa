"""The native methods' ``light_intensity`` setting: "ignored" (the authors' SSD-GS / GS³ convention)
trains and scores exactly as the default does on a copy of the scene with every ``pl_intensity``
removed (which olatbench reads as intensity 1, unknown), seed for seed; "recorded" (the default)
differs on a scene whose intensity varies."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pytest
import test_runner_support as support

from olatbench.bench.execute import run_job
from olatbench.bench.plan import make_plan
from olatbench.bench.results import read_results
from olatbench.datasets import load_scene
from olatbench.methods.registry import get_method

pytest.importorskip("olatbench.gaussians.shadow")


def strip_intensity(src: Path, dst: Path) -> Path:
    """A copy of the NRHints scene ``src`` whose transforms files have no ``pl_intensity``."""
    shutil.copytree(src, dst)
    for path in dst.glob("transforms_*.json"):
        meta = json.loads(path.read_text())
        for frame in meta["frames"]:
            del frame["pl_intensity"]
        path.write_text(json.dumps(meta))
    return dst


def trained(method: str, data: Path, out: Path, **config) -> dict:
    job = make_plan(
        method,
        support.tiny_suite(scenes=("Alpha",)),
        out,
        variants=["mini"],
        iterations=6,
        data_root=data,
        progress=False,
    )[0]
    job = dataclasses.replace(
        job, config={**job.config, "num_init_gaussians": 100, "shadow_resolution": 16, **config}
    ).with_id()
    outcome = run_job(job, progress=False)
    assert outcome.status == "done", (Path(job.folder) / "error.txt").read_text()
    return read_results(Path(job.folder) / "results.json")


@pytest.mark.parametrize("method", ["ssdgs", "gs3"])
def test_ignored_intensity_trains_as_the_scene_without_pl_intensity(method, tmp_path):
    data = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",), size=(24, 16))
    bare = strip_intensity(data / "Alpha", tmp_path / "bare" / "Alpha").parent
    recorded = {f.light.intensity[0] for f in load_scene(data / "Alpha", "nrhints").split("train")}
    # the intensity varies over the frames: ignoring it changes the images' meaning
    assert len(recorded) > 1
    assert all(
        not f.light.intensity_known and list(f.light.intensity) == [1.0, 1.0, 1.0]
        for f in load_scene(bare / "Alpha", "nrhints").split("train")
    )

    ignored = trained(method, data, tmp_path / "runs-ignored", light_intensity="ignored")
    stripped = trained(method, bare, tmp_path / "runs-bare")
    default = trained(method, data, tmp_path / "runs-recorded")

    assert ignored["job"]["config"]["light_intensity"] == "ignored"
    assert default["job"]["config"]["light_intensity"] == "recorded"
    assert ignored["metrics"] == stripped["metrics"]  # every view's PSNR/SSIM/LPIPS, bit for bit
    assert ignored["metrics"] != default["metrics"]


def test_light_intensity_is_checked_by_name():
    cls = get_method("ssdgs")
    with pytest.raises(
        ValueError, match=r"light_intensity must be one of \('recorded', 'ignored'\), not 'off'"
    ):
        cls.resolve_config(None, light_intensity="off")
