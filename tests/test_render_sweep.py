"""Relighting sweeps: trajectory geometry, frame counts, and `olatbench render` end to end with a
trivial method."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree

from olatbench.bench.checkpoints import save_checkpoint
from olatbench.cli import main
from olatbench.datasets.cameras import look_at
from olatbench.datasets.records import Camera, PointLight
from olatbench.methods.base import Method
from olatbench.methods.registry import register
from olatbench.reports.jobfolder import JobFolder, read_png
from olatbench.reports.sweeps import (
    orbit_frame,
    rotation_matrix,
    subsample,
    trajectory,
)


def ring_camera(
    azimuth_deg: float, centre=(1.0, -2.0, 0.5), radius: float = 4.0, height: float = 1.0
) -> Camera:
    angle = np.deg2rad(azimuth_deg)
    eye = np.array(centre) + np.array([radius * np.cos(angle), radius * np.sin(angle), height])
    K = np.array([[20.0, 0, 8], [0, 20.0, 6], [0, 0, 1]])
    return Camera(K, look_at(eye, np.array(centre), up=np.array([0.0, 0.0, 1.0])), 16, 12)


def test_rotation_matrix_closed_form():
    np.testing.assert_allclose(rotation_matrix([0, 0, 1], 90) @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    rotation = rotation_matrix([1, 2, 3], 37.0)
    np.testing.assert_allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(rotation) == pytest.approx(1.0)
    np.testing.assert_allclose(
        rotation @ (np.array([1, 2, 3]) / np.sqrt(14)), np.array([1, 2, 3]) / np.sqrt(14)
    )


def test_orbit_frame_recovers_centre_and_up():
    cameras = [ring_camera(a) for a in (0, 50, 130, 220, 300)]
    centre, up = orbit_frame(cameras)
    np.testing.assert_allclose(centre, [1.0, -2.0, 0.5], atol=1e-9)
    assert up @ np.array([0, 0, 1.0]) > 0.9
    with pytest.raises(ValueError, match="at least two"):
        orbit_frame(cameras[:1])


def test_light_orbit_keeps_distance_and_height_and_closes_the_loop():
    camera = ring_camera(0)
    centre, up = np.array([1.0, -2.0, 0.5]), np.array([0.0, 0.0, 1.0])
    light = PointLight(np.array([4.0, -2.0, 3.0]))
    frames = trajectory("light-orbit", camera, light, centre, up)
    assert len(frames) == 150  # 360° / 2.4°
    positions = np.array([f.light.position for f in frames])
    np.testing.assert_allclose(
        np.linalg.norm(positions - centre, axis=1), np.linalg.norm(light.position - centre)
    )
    np.testing.assert_allclose(positions[:, 2], 3.0)
    np.testing.assert_allclose(positions[0], light.position)
    azimuths = np.degrees(
        np.unwrap(np.arctan2(positions[:, 1] - centre[1], positions[:, 0] - centre[0]))
    )
    np.testing.assert_allclose(np.diff(azimuths), 2.4)
    assert all(f.camera is camera for f in frames)


def test_view_orbit_and_paper_trajectory_counts_and_back_view():
    camera = ring_camera(0)
    centre, up = np.array([1.0, -2.0, 0.5]), np.array([0.0, 0.0, 1.0])
    light = PointLight(np.array([4.0, -2.0, 3.0]))
    assert len(trajectory("view-orbit", camera, light, centre, up)) == 180
    paper = trajectory("paper", camera, light, centre, up)
    assert len(paper) == 150 + 90 + 150 + 90
    back = paper[150 + 89].camera
    np.testing.assert_allclose(back.position, ring_camera(180).position, atol=1e-9)
    np.testing.assert_allclose(back.c2w[:3, :3], ring_camera(180).c2w[:3, :3], atol=1e-9)
    np.testing.assert_allclose(paper[-1].camera.position, camera.position, atol=1e-9)
    assert [paper[i].phase for i in (0, 149, 150, 239, 240, 389, 390, 479)] == [
        "light (front)",
        "light (front)",
        "camera to back",
        "camera to back",
        "light (back)",
        "light (back)",
        "camera to front",
        "camera to front",
    ]
    with pytest.raises(ValueError, match="unknown sweep"):
        trajectory("spiral", camera, light, centre, up)
    assert len(subsample(paper, 7)) == 7 and subsample(paper, 7)[0] is paper[0]


class ToyRelight(Method):
    """A method whose render depends only on the light's azimuth and a stored gain."""

    name = "toy-relight"

    @dataclass
    class Config:
        iterations: int = 1

    config_class = Config

    def __init__(self, config) -> None:
        super().__init__(config)
        self.gain = torch.tensor(0.0)

    def setup(self, train, device, seed) -> None:
        """As in the runner, `setup` sees the training views before the checkpoint is loaded."""
        assert len(train) == 6 and train.images.shape == (6, 12, 16, 3)
        self.gain = torch.tensor(-1.0)  # overwritten by the checkpoint

    def train_step(self, step):  # pragma: no cover
        raise AssertionError("rendering a sweep must not train")

    def render(self, camera, light):
        azimuth = float(np.arctan2(light.position[1], light.position[0]))
        value = float(self.gain) * (0.5 + 0.4 * np.cos(azimuth))
        return {
            "rgb": torch.full((camera.height, camera.width, 3), value),
            "shadow": torch.full((camera.height, camera.width), 0.25),
        }

    def state_dict(self):
        return {"gain": self.gain.clone()}

    def load_state_dict(self, state) -> None:
        self.gain = state["gain"]


def make_job(tmp_path: Path) -> Path:
    register("toy-relight", ToyRelight)
    scene = tmp_path / "data" / "Toy"
    write_nrhints_tree(scene, n_train=6, n_test=2, size=(16, 12))
    folder = tmp_path / "runs" / "nrhints" / "toy-relight" / "default" / "Toy" / "seed0"
    folder.mkdir(parents=True)
    job = {
        "id": "job123",
        "method": "toy-relight",
        "method_ref": "test_render_sweep:ToyRelight",
        "variant": "default",
        "suite": "nrhints",
        "scene": "Toy",
        "seed": 0,
        "config": {"iterations": 1},
        "scene_path": str(scene),
        "scene_format": "nrhints",
        "colourspace": "srgb",
        "resolution": None,
        "train_split": "train",
        "test_split": "test",
        "protocol": "olatbench-v1",
        "protocol_version": 1,
        "data_manifest": None,
        "code": "x",
        "folder": "",
        "device": "cpu",
    }
    (folder / "job.json").write_text(json.dumps(job))
    (folder / "config.json").write_text(json.dumps(job["config"]))
    save_checkpoint(folder, 1, {"gain": torch.tensor(1.0)}, "job123", train_seconds=1.0)
    return folder


def test_cli_render_writes_the_requested_frames_and_video(tmp_path):
    folder = make_job(tmp_path)
    result = CliRunner().invoke(
        main,
        [
            "render",
            str(folder),
            "--sweep",
            "light-orbit",
            "--frames",
            "6",
            "-o",
            str(tmp_path / "video"),
        ],
    )
    assert result.exit_code == 0, result.output
    frames = sorted((tmp_path / "video" / "light-orbit_frames").glob("*.png"))
    assert [f.name for f in frames] == [f"{i:05d}.png" for i in range(6)]
    capture = cv2.VideoCapture(str(tmp_path / "video" / "light-orbit.mp4"))
    count = 0
    while capture.read()[0]:
        count += 1
    capture.release()
    assert count == 6
    # the first frame is the method's render for the test frame's own light; the light moves, the
    # image changes
    job = JobFolder.open(folder)
    start = job.load_scene().split("test")[0]
    azimuth = np.arctan2(start.light.position[1], start.light.position[0])
    expected = 0.5 + 0.4 * np.cos(azimuth)
    first = read_png(frames[0])
    assert first.shape == (12, 16, 3)
    assert np.abs(first - expected).max() <= 0.5 / 255 + 1e-6
    assert len({round(float(read_png(f).mean()), 3) for f in frames}) > 1


def test_cli_render_component_and_errors(tmp_path):
    folder = make_job(tmp_path)
    result = CliRunner().invoke(
        main,
        [
            "render",
            str(folder),
            "--sweep",
            "paper",
            "--frames",
            "3",
            "--component",
            "shadow",
            "-o",
            str(tmp_path / "v"),
        ],
    )
    assert result.exit_code == 0, result.output
    assert np.allclose(
        read_png(tmp_path / "v" / "paper_frames" / "00002.png"), 64 / 255, atol=1 / 255
    )
    missing = CliRunner().invoke(
        main,
        [
            "render",
            str(folder),
            "--frames",
            "2",
            "--component",
            "specular",
            "-o",
            str(tmp_path / "w"),
        ],
    )
    assert missing.exit_code == 2 and "renders no component 'specular'" in missing.output
    assert "it renders rgb, shadow (choose one with --component)" in missing.output
    # the job is fine: the advice is about the option
    assert "olatbench status" not in missing.output
    near = CliRunner().invoke(
        main,
        ["render", str(folder), "--frames", "2", "--component", "shadw", "-o", str(tmp_path / "w")],
    )
    assert near.exit_code == 2 and "(did you mean 'shadow'?)" in near.output
    frame = CliRunner().invoke(
        main, ["render", str(folder), "--start-frame", "r_9999", "-o", str(tmp_path / "w")]
    )
    assert (
        frame.exit_code == 2
        and "no frame 'r_9999'" in frame.output
        and "olatbench status" not in frame.output
    )
    assert "the test frames are" in frame.output and "leave --start-frame out" in frame.output
    not_a_job = CliRunner().invoke(main, ["render", str(tmp_path)])
    assert not_a_job.exit_code == 2 and "job.json: not found" in not_a_job.output
