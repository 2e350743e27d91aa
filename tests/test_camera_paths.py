"""`olatbench render --camera-path` (nerfstudio camera-path JSON) and `--orbit`, under `--light` /
`--light-path` (`olatbench.reports.camera_paths`)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch
from click.testing import CliRunner
from datasets_trees import write_nrhints_tree

from olatbench.bench.checkpoints import save_checkpoint
from olatbench.cli import main
from olatbench.datasets import colour
from olatbench.datasets.cameras import opencv_to_opengl
from olatbench.methods.base import Method
from olatbench.methods.registry import register
from olatbench.reports.camera_paths import CameraPathError, orbit_cameras, read_camera_path
from olatbench.reports.jobfolder import JobFolder, read_png
from olatbench.reports.sweeps import orbit_frame
from olatbench.reports.video import display_image


class RayColour(Method):
    """Each pixel's colour is its world-space ray direction (from K and c2w, pixel centres at +0.5),
    tinted by the light's position: any error in a camera's pose or intrinsics, or in the light,
    changes the image."""

    name = "ray-colour"

    @dataclass
    class Config:
        iterations: int = 1

    config_class = Config

    def setup(self, train, device, seed) -> None:
        pass

    def train_step(self, step):  # pragma: no cover
        raise AssertionError("rendering must not train")

    def render(self, camera, light):
        u, v = np.meshgrid(np.arange(camera.width) + 0.5, np.arange(camera.height) + 0.5)
        pixels = np.stack([u, v, np.ones_like(u)], axis=-1) @ np.linalg.inv(camera.K).T
        rays = pixels @ camera.c2w[:3, :3].T
        rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
        tint = 0.5 + 0.05 * np.tanh(np.asarray(light.position, dtype=np.float64))
        return {"rgb": torch.from_numpy((0.5 + 0.4 * rays) * tint).float()}

    def state_dict(self):
        return {}

    def load_state_dict(self, state) -> None:
        pass


def make_job(tmp_path: Path) -> Path:
    """A finished ray-colour job on an NRHints scene whose cameras have square pixels and centred
    principal points (``camera_angle_x``: what a nerfstudio camera path can express)."""
    register("ray-colour", RayColour)
    scene = tmp_path / "data" / "Rays"
    write_nrhints_tree(scene, n_train=5, n_test=2, size=(20, 14), intrinsics=False)
    folder = tmp_path / "runs" / "nrhints" / "ray-colour" / "default" / "Rays" / "seed0"
    folder.mkdir(parents=True)
    job = {
        "id": "job456",
        "method": "ray-colour",
        "method_ref": "test_camera_paths:RayColour",
        "variant": "default",
        "suite": "nrhints",
        "scene": "Rays",
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
    save_checkpoint(folder, 1, {}, "job456", train_seconds=1.0)
    return folder


def eight_bit(png: Path) -> np.ndarray:
    return np.rint(read_png(png) * 255.0).astype(np.uint8)


def nerfstudio_path(cameras, fps: float = 24.0) -> dict:
    """A camera path as nerfstudio's viewer writes it: OpenGL camera-to-world flattened row-major,
    vertical fov."""
    width, height = cameras[0].width, cameras[0].height
    frames = [
        {
            "camera_to_world": opencv_to_opengl(camera.c2w).reshape(-1).tolist(),
            "fov": math.degrees(2 * math.atan(0.5 * height / camera.fy)),
            "aspect": width / height,
        }
        for camera in cameras
    ]
    return {
        "camera_type": "perspective",
        "render_width": width,
        "render_height": height,
        "fps": fps,
        "seconds": len(frames) / fps,
        "camera_path": frames,
    }


def test_a_path_through_the_training_cameras_gives_back_those_cameras(tmp_path):
    train = JobFolder.open(make_job(tmp_path)).load_scene().split("train")
    file = tmp_path / "path.json"
    file.write_text(json.dumps(nerfstudio_path([frame.camera for frame in train])))
    read = read_camera_path(file)
    assert read.fps == 24.0 and len(read.cameras) == len(train)
    for camera, frame in zip(read.cameras, train, strict=True):
        np.testing.assert_allclose(camera.c2w, frame.camera.c2w, atol=1e-12)
        np.testing.assert_allclose(camera.K, frame.camera.K, rtol=1e-12)
        assert (camera.width, camera.height) == (frame.camera.width, frame.camera.height)


def test_render_along_a_camera_path_matches_rendering_the_training_cameras(tmp_path):
    folder = make_job(tmp_path)
    train = JobFolder.open(folder).load_scene().split("train")
    file = tmp_path / "path.json"
    file.write_text(json.dumps(nerfstudio_path([frame.camera for frame in train])))
    result = CliRunner().invoke(
        main,
        [
            "render",
            str(folder),
            "--camera-path",
            str(file),
            "--light",
            "2",
            "-o",
            str(tmp_path / "out"),
        ],
    )
    assert result.exit_code == 0, result.output
    assert (tmp_path / "out" / "camera-path.mp4").stat().st_size > 0
    frames = sorted((tmp_path / "out" / "camera-path_frames").glob("*.png"))
    assert len(frames) == len(train)
    method = RayColour(RayColour.Config())
    for png, frame in zip(frames, train, strict=True):
        direct = display_image(method.render(frame.camera, train[2].light)["rgb"], "srgb")
        # the same 8-bit image
        np.testing.assert_array_equal(eight_bit(png), colour.quantize_8bit(direct))


def test_orbit_cameras_keep_elevation_radius_and_look_at_the_centre():
    from olatbench.datasets.cameras import intrinsics_from_fov, look_at
    from olatbench.datasets.records import Camera

    centre, up = np.array([1.0, -2.0, 0.5]), np.array([0.0, 0.0, 1.0])
    template = Camera(
        intrinsics_from_fov(0.8, 16, 12), look_at([5.0, -2.0, 0.5], centre, up), 16, 12
    )
    cameras = orbit_cameras(template, centre, up, elevation=30.0, radius=3.0, count=8)
    assert len(cameras) == 8
    for index, camera in enumerate(cameras):
        offset = camera.position - centre
        assert np.linalg.norm(offset) == pytest.approx(3.0)
        assert math.degrees(math.asin(offset @ up / 3.0)) == pytest.approx(30.0)
        assert math.degrees(math.atan2(offset[1], offset[0])) % 360 == pytest.approx(
            45.0 * index, abs=1e-9
        )
        # looks at the centre
        np.testing.assert_allclose(camera.c2w[:3, 2], -offset / 3.0, atol=1e-12)
        np.testing.assert_array_equal(camera.K, template.K)
    with pytest.raises(CameraPathError, match="elevation"):
        orbit_cameras(template, centre, up, elevation=90.0, radius=3.0, count=8)


def test_cli_orbit_under_a_light_path(tmp_path):
    folder = make_job(tmp_path)
    scene = JobFolder.open(folder).load_scene()
    lights = tmp_path / "lights.json"
    lights.write_text(
        json.dumps({"lights": [{"position": [4.0, 0.0, float(z)]} for z in range(6)]})
    )
    result = CliRunner().invoke(
        main,
        [
            "render",
            str(folder),
            "--orbit",
            "--frames",
            "6",
            "--elevation",
            "10",
            "--light-path",
            str(lights),
            "-o",
            str(tmp_path / "out"),
            "--fps",
            "12",
        ],
    )
    assert result.exit_code == 0, result.output
    frames = sorted((tmp_path / "out" / "orbit_frames").glob("*.png"))
    assert len(frames) == 6
    centre, up = orbit_frame([frame.camera for frame in scene.split("train")])
    radius = np.mean(
        [np.linalg.norm(frame.camera.position - centre) for frame in scene.split("train")]
    )
    camera = orbit_cameras(scene.split("test")[0].camera, centre, up, 10.0, radius, 6)[3]
    light = scene.split("train")[0].light.__class__(np.array([4.0, 0.0, 3.0]))
    expected = colour.quantize_8bit(
        display_image(RayColour(RayColour.Config()).render(camera, light)["rgb"], "srgb")
    )
    np.testing.assert_array_equal(eight_bit(frames[3]), expected)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--camera-path", "{bad}"], "camera_path[1].fov: must be positive"),
        (["--camera-path", "{good}", "--light", "99"], "light 99: the training split has 5 frames"),
        (
            ["--camera-path", "{good}", "--light", "1,2"],
            "expected a training light index (0 … 4) or a position x,y,z",
        ),
        (["--orbit", "--frames", "3", "--light-path", "{lights}"], "2 lights for 3 cameras"),
        (["--orbit", "--camera-path", "{good}"], "not both"),
        (["--light", "0"], "--light and --light-path go with --camera-path or --orbit"),
    ],
)
def test_cli_camera_path_errors_name_the_file_and_field(tmp_path, args, message):
    folder = make_job(tmp_path)
    camera = JobFolder.open(folder).load_scene().split("train")[0].camera
    good = nerfstudio_path([camera, camera])
    bad = json.loads(json.dumps(good))
    bad["camera_path"][1]["fov"] = -3
    files = {
        "good": good,
        "bad": bad,
        "lights": {"lights": [{"position": [1, 2, 3]}, {"position": [3, 2, 1]}]},
    }
    for name, content in files.items():
        (tmp_path / f"{name}.json").write_text(json.dumps(content))
    args = [arg.format(**{name: tmp_path / f"{name}.json" for name in files}) for arg in args]
    result = CliRunner().invoke(main, ["render", str(folder), *args, "-o", str(tmp_path / "out")])
    assert result.exit_code == 2 and message in result.output, result.output
    assert "Traceback" not in result.output and "olatbench status" not in result.output
