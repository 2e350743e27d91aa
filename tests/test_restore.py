"""`olatbench.bench.restore`: a trained method rebuilt from its job folder without its training
images."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import test_runner_support as support
import torch
from click.testing import CliRunner
from trained_jobs import train_tiny_ssdgs

from olatbench.bench.jobs import Job
from olatbench.bench.plan import make_plan
from olatbench.bench.restore import RestoreError, restore
from olatbench.cli import main
from olatbench.datasets import colour, load_scene
from olatbench.datasets.records import Frame
from olatbench.reports.jobfolder import JobFolder, read_png

pytest.importorskip("olatbench.gaussians.shadow")


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> Path:
    """A finished SSD-GS job whose training views have camera and light refinements
    (per frame id)."""
    return train_tiny_ssdgs(
        tmp_path_factory.mktemp("restore"), refine_camera=True, refine_light=True
    )


def count_train_loads(monkeypatch, job: Job) -> list[str]:
    """Patch `Frame.load` to record every training frame whose image is read."""
    train_ids = {f.frame_id for f in load_scene(job.scene_path).split(job.train_split)}
    loaded: list[str] = []
    real_load = Frame.load

    def load(self, *args, **kwargs):
        if self.frame_id in train_ids:
            loaded.append(self.frame_id)
        return real_load(self, *args, **kwargs)

    monkeypatch.setattr(Frame, "load", load)
    return loaded


def test_job_from_json_inverts_to_json(tmp_path):
    data = support.write_tiny_data(tmp_path / "data", scenes=("Alpha",))
    job = make_plan(
        "trivial",
        support.tiny_suite(scenes=("Alpha",)),
        tmp_path / "runs",
        data_root=data,
        resolution=(32, 24),
        progress=False,
    )[0]
    assert job.resolution == (32, 24) and job.id
    assert Job.from_json(job.to_json()) == job
    # the job.json text, parsed back
    assert Job.from_json(json.loads(json.dumps(job.to_json()))) == job
    edited = {**job.to_json(), "seed": 7}
    with pytest.raises(ValueError, match=r"identity does not match its fields \(seed\)"):
        Job.from_json(edited)
    with pytest.raises(ValueError, match="unknown keys colour"):
        Job.from_json({**job.to_json(), "colour": "srgb"})
    without = {k: v for k, v in job.to_json().items() if k not in ("scene_path", "identity")}
    with pytest.raises(ValueError, match="missing keys scene_path"):
        Job.from_json(without)


def test_restore_reads_no_training_image_and_reproduces_the_runners_renders(trained, monkeypatch):
    job = Job.from_json(json.loads((trained / "job.json").read_text()))
    loaded = count_train_loads(monkeypatch, job)
    method, restored = restore(trained)
    assert loaded == [] and method.train_views.views.images is None
    assert restored.id == job.id and restored.folder == str(trained)
    refinement = method.pose_refinement.tangents.detach()
    # the training views' own poses differ from the dataset's
    assert float(refinement.abs().max()) > 0
    scene = load_scene(job.scene_path)
    # train frames are found by their pose and light: their refinements apply
    for split in ("train", "test"):
        for frame in scene.split(split):
            rgb = method.render(frame.camera, frame.light)["rgb"].numpy()
            srgb = colour.quantize_8bit(
                colour.convert_colourspace(np.clip(rgb, 0, 1), job.colourspace, "srgb")
            )
            stored = np.round(
                read_png(JobFolder.open(trained).render_path(split, frame.frame_id)) * 255
            )
            assert np.abs(srgb.astype(float) - stored).max() <= 1, (split, frame.frame_id)


def test_render_sweep_of_a_trained_job_loads_no_training_image(trained, monkeypatch, tmp_path):
    job = Job.from_json(json.loads((trained / "job.json").read_text()))
    loaded = count_train_loads(monkeypatch, job)
    result = CliRunner().invoke(
        main,
        [
            "render",
            str(trained),
            "--sweep",
            "light-orbit",
            "--frames",
            "3",
            "-o",
            str(tmp_path / "video"),
        ],
    )
    assert result.exit_code == 0, result.output
    assert len(list((tmp_path / "video" / "light-orbit_frames").glob("*.png"))) == 3
    assert loaded == []


def test_restore_errors_name_the_file(trained, tmp_path):
    with pytest.raises(RestoreError, match=r"job\.json: not found"):
        restore(tmp_path)
    copy = tmp_path / "copy"
    shutil.copytree(trained, copy)
    (copy / "config.json").write_text(
        json.dumps({**json.loads((copy / "config.json").read_text()), "sh": 1})
    )
    with pytest.raises(RestoreError, match=r"config\.json: differs from the config in job\.json"):
        restore(copy)
    shutil.copy(trained / "config.json", copy / "config.json")
    job = json.loads((copy / "job.json").read_text())
    (copy / "job.json").write_text(
        json.dumps({**job, "method_ref": "olatbench.methods.nothing:Nope"})
    )
    with pytest.raises(
        RestoreError, match=r"method 'ssdgs' .* cannot be imported .* known methods: .*ssdgs"
    ):
        restore(copy)
    (copy / "job.json").write_text(json.dumps(job))
    checkpoint = next((copy / "checkpoints").iterdir())
    checkpoint.rename(checkpoint.with_name("step_00000003.pt"))
    with pytest.raises(
        RestoreError, match="newest checkpoint is at step 3 of 16; the job is not finished"
    ):
        restore(copy)


def test_resume_and_restore_share_the_checkpoint_loader(trained):
    """`load_state` loads exactly the checkpoint's state: a restored model's parameters are the
    saved ones."""
    method, job = restore(trained)
    saved = torch.load(next((trained / "checkpoints").iterdir()), weights_only=True)["method"]
    assert torch.equal(method.model.state_dict()["means"], saved["model"]["means"])
    assert method.step == job.iterations
