"""No dependence on the world frame (#46): `olatbench.datasets.similarity` and the canonical frame
the Gaussian methods train in.

A scene and a similarity-transformed copy of it (scale 10, a rotation, a translation of many scene
radii; light intensities × 10² so the irradiance is unchanged; the same images) must give the same
canonical cameras and lights to rounding, and so the same initial Gaussians, learning rates,
density-control thresholds and training losses.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
import torch
from moved_scenes import ROTATION, SCALE, TRANSLATION, rotation
from ssdgs_scenes import sphere_views

from olatbench.datasets.cameras import look_at
from olatbench.datasets.records import Camera, PointLight
from olatbench.datasets.similarity import (
    CANONICAL_CAMERA_DISTANCE,
    RigError,
    Similarity,
    canonical_frame,
    quaternion_product,
    rig_vertical,
    rotation_quaternion,
)
from olatbench.methods.base import Views

# s = 10, a rotation, and a translation of ~60 units: 60 sphere radii, 15 camera distances before
# scaling
MOVE = Similarity(SCALE, ROTATION, TRANSLATION)


def moved(views: Views, move: Similarity = MOVE) -> Views:
    """The views of the moved scene, written out by hand (not with `Similarity.camera`/`light`)."""
    cameras = []
    for camera in views.cameras:
        c2w = np.eye(4)
        c2w[:3, :3] = move.rotation @ camera.c2w[:3, :3]
        c2w[:3, 3] = move.scale * move.rotation @ camera.c2w[:3, 3] + move.translation
        cameras.append(dataclasses.replace(camera, c2w=c2w))
    lights = [
        dataclasses.replace(
            light,
            position=move.scale * move.rotation @ light.position + move.translation,
            intensity=light.intensity * move.scale**2,
        )
        for light in views.lights
    ]
    return dataclasses.replace(views, cameras=cameras, lights=lights)


def fitted(views: Views) -> Views:
    """The views with the frame the runner gives a scene outside the built-in suites."""
    return dataclasses.replace(views, frame=canonical_frame(views.cameras))


def pixel(camera: Camera, point: np.ndarray) -> np.ndarray:
    """Pixel coordinates and depth of a world point (the projection, written here)."""
    p = camera.w2c() @ np.append(point, 1.0)
    return np.array([*(camera.K @ (p[:3] / p[2]))[:2], p[2]])


def test_similarity_moves_cameras_lights_and_gaussians_consistently():
    rng = np.random.default_rng(0)
    views = sphere_views(3, size=16)
    point = rng.normal(size=3) * 0.3
    for camera, light in zip(views.cameras, views.lights, strict=True):
        moved_camera, moved_light = MOVE.camera(camera), MOVE.light(light)
        moved_point = MOVE.points(point)
        # the point lands on the same pixel, at the depth × scale
        np.testing.assert_allclose(
            pixel(moved_camera, moved_point), pixel(camera, point) * [1, 1, MOVE.scale]
        )
        # the irradiance I / d² at the point is unchanged
        np.testing.assert_allclose(
            moved_light.irradiance_scale(moved_point[None]), light.irradiance_scale(point[None])
        )
    inverse = MOVE.inverse()
    np.testing.assert_allclose(inverse.points(MOVE.points(point)), point, atol=1e-12)
    np.testing.assert_allclose(MOVE.then(inverse).matrix(), np.eye(4), atol=1e-12)
    np.testing.assert_allclose(
        MOVE.matrix() @ np.append(point, 1.0), np.append(MOVE.points(point), 1.0)
    )
    # quaternions: the moved Gaussian's rotation matrix is R · (its own); a quaternion's norm is
    # kept
    quats = rng.normal(size=(5, 4))
    moved_quats = MOVE.quaternions(quats)
    np.testing.assert_allclose(np.linalg.norm(moved_quats, axis=1), np.linalg.norm(quats, axis=1))
    for q, q_moved in zip(quats, moved_quats, strict=True):
        np.testing.assert_allclose(
            quaternion_matrix(q_moved), MOVE.rotation @ quaternion_matrix(q), atol=1e-12
        )
    np.testing.assert_allclose(MOVE.log_scales(np.zeros(3)), np.full(3, np.log(10.0)))
    assert Similarity.identity().is_identity and not MOVE.is_identity
    assert Similarity.from_dict(MOVE.to_dict()).allclose(MOVE)


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """The rotation of a (not necessarily unit) wxyz quaternion, written here."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


@pytest.mark.parametrize("angle", [0.0, 0.3, np.pi / 2, 2.0, np.pi - 1e-3, np.pi])
@pytest.mark.parametrize("axis", [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, -2, 0.5)])
def test_rotation_quaternion_inverts_the_quaternion_matrix(axis, angle):
    matrix = rotation(axis, angle)
    q = rotation_quaternion(matrix)
    np.testing.assert_allclose(np.linalg.norm(q), 1.0)
    np.testing.assert_allclose(quaternion_matrix(q), matrix, atol=1e-12)
    np.testing.assert_allclose(quaternion_product(q, [1.0, 0, 0, 0]), q)


def canonical_records(views: Views) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    canonical = views.in_frame()
    return (
        np.stack([c.c2w for c in canonical.cameras]),
        np.stack([lt.position for lt in canonical.lights]),
        np.stack([lt.intensity for lt in canonical.lights]),
    )


def test_canonical_frame_of_a_moved_scene_is_the_original_ones_to_rounding():
    views = fitted(sphere_views(12, size=16))
    copy = fitted(moved(views))
    for original, other in zip(canonical_records(views), canonical_records(copy), strict=True):
        np.testing.assert_allclose(other, original, rtol=1e-12, atol=1e-12)
    # the fit moves with the scene: canonical ∘ MOVE⁻¹ of the original is the copy's
    assert MOVE.inverse().then(views.frame).allclose(copy.frame)
    # what the frame is: the axes' meeting point (the sphere's centre) at the origin, cameras at the
    # median distance
    np.testing.assert_allclose(views.frame.points(np.zeros(3)), np.zeros(3), atol=1e-12)
    distances = np.linalg.norm(canonical_records(copy)[0][:, :3, 3], axis=1)
    np.testing.assert_allclose(np.median(distances), CANONICAL_CAMERA_DISTANCE)
    # without the frame (the dataset's own, as for the built-in suites) the two scenes differ
    assert not np.allclose(
        canonical_records(moved(views))[0], canonical_records(views)[0], atol=1.0
    )


def forward_rig(
    near: float | None = 2.0, far: float | None = 6.0, toe_in: float = 0.0
) -> list[Camera]:
    """Four cameras in the plane z = 0 looking along +z (OpenCV axes), as a phone capture of a scene
    ahead; ``toe_in`` turns each towards the x = y = 0 axis by that many radians per unit of
    offset."""
    K = np.array([[20.0, 0, 8], [0, 20.0, 8], [0, 0, 1]])
    cameras = []
    for x, y in ((0, 0), (1, 0), (0, 1), (1, 1.5)):
        turn = rotation([y, -x, 0.0], toe_in * np.hypot(x, y)) if x or y else np.eye(3)
        c2w = np.block([[turn, np.array([[x], [y], [0.0]])], [np.zeros((1, 3)), 1.0]])
        cameras.append(Camera(K, c2w, 16, 16, near=near, far=far))
    return cameras


def test_canonical_frame_of_degenerate_rigs_still_moves_with_the_scene():
    """Forward-facing cameras (parallel axes: no point where they meet; their near/far give the
    depth) and cameras rolled every way (no mean up)."""
    rng = np.random.default_rng(1)
    rolled = [
        dataclasses.replace(
            c,
            c2w=c.c2w
            @ np.block([[rotation([0, 0, 1], a), np.zeros((3, 1))], [np.zeros((1, 3)), 1.0]]),
        )
        for c, a in zip(sphere_views(9, size=16).cameras, rng.uniform(0, 2 * np.pi, 9), strict=True)
    ]
    for cameras in (forward_rig(), rolled):
        views = Views(
            cameras=cameras,
            lights=[PointLight(np.zeros(3))] * len(cameras),
            images=None,
            frame_ids=[str(i) for i in range(len(cameras))],
        )
        copy = moved(views)
        copy = dataclasses.replace(
            copy,
            cameras=[  # near/far in the moved scene's units, by hand
                dataclasses.replace(
                    c,
                    near=None if c.near is None else c.near * SCALE,
                    far=None if c.far is None else c.far * SCALE,
                )
                for c in copy.cameras
            ],
        )
        for original, other in zip(
            canonical_records(fitted(views)), canonical_records(fitted(copy)), strict=True
        ):
            np.testing.assert_allclose(other, original, rtol=1e-10, atol=1e-10)


def test_a_forward_facing_rig_is_centred_ahead_of_the_cameras_at_its_depth():
    """Parallel axes: the origin is the middle of the near/far range ahead of the cameras' mean
    position, as LLFF fits its bounds; axes turned in by more than `MIN_AXES_SPREAD_DEG` meet at a
    point, which is taken."""
    cameras = forward_rig(near=2.0, far=6.0)
    frame = canonical_frame(cameras)
    mean = np.mean([c.position for c in cameras], axis=0)
    np.testing.assert_allclose(
        frame.points(mean + np.array([0.0, 0.0, 4.0])), np.zeros(3), atol=1e-12
    )
    # ahead of every camera, 4 units away (median)
    canonical = [frame.camera(camera) for camera in cameras]
    assert all(-(c.position @ c.c2w[:3, 2]) > 3.0 for c in canonical)
    np.testing.assert_allclose(
        np.median([np.linalg.norm(c.position) for c in canonical]), CANONICAL_CAMERA_DISTANCE
    )
    from olatbench.methods.initialisation import initial_ball

    # the random Gaussians start there, not at the cameras
    centre, radius = initial_ball(canonical, None)
    np.testing.assert_allclose(centre, np.zeros(3), atol=1e-9)
    assert radius < CANONICAL_CAMERA_DISTANCE
    # ≈ 9° rms: they meet at a point, no near/far needed
    converging = forward_rig(near=None, far=None, toe_in=0.25)
    centre = canonical_frame(converging).inverse().points(np.zeros(3))
    assert centre[2] > 1.0 and np.all(
        [(centre - c.position) @ c.c2w[:3, 2] > 0 for c in converging]
    )


RIGS_WITHOUT_A_CENTRE = {  # name: (cameras, what the error says)
    "one camera": (lambda: forward_rig()[:1], "a single training camera"),
    "one pose": (lambda: [forward_rig()[0]] * 5, "all 5 training cameras have one pose"),
    "one point (a panorama)": (
        lambda: [
            dataclasses.replace(
                forward_rig()[0],
                c2w=np.block([[rotation([0, 1, 0], a), np.zeros((3, 1))], [np.zeros((1, 3)), 1.0]]),
            )
            for a in np.linspace(0, 2 * np.pi, 8, endpoint=False)
        ],
        "sit at one point and only turn about it",
    ),
    "looking outwards": (
        lambda: [
            dataclasses.replace(c, c2w=look_at(c.position, 2.0 * c.position, [0.0, 0.0, 1.0]))
            for c in sphere_views(8, size=16).cameras
        ],
        "meet behind or among them",
    ),
    "facing one way without near/far": (
        lambda: forward_rig(near=None, far=None),
        "camera_near/camera_far",
    ),
}


@pytest.mark.parametrize("rig", list(RIGS_WITHOUT_A_CENTRE))
def test_rigs_without_a_centre_are_refused_naming_why(rig):
    make, phrase = RIGS_WITHOUT_A_CENTRE[rig]
    with pytest.raises(RigError, match=re.escape(phrase)):
        canonical_frame(make())


def test_canonical_up_is_the_vertical_of_a_levelled_rig_and_the_mean_up_otherwise():
    """Cameras levelled by a look-at (no roll), bunched on one side: the mean up leans towards them;
    the vertical orthogonal to every right axis does not. Rolled or forward-facing cameras do not
    pin it down (None)."""
    K = np.array([[20.0, 0, 8], [0, 20.0, 8], [0, 0, 1]])
    tilt = rotation([1.0, -2.0, 0.5], 0.7)  # the rig's vertical is tilt @ z
    centre = np.array([0.3, -1.0, 2.0])
    rng = np.random.default_rng(4)
    cameras = []
    for azimuth, elevation in zip(
        rng.uniform(0.0, 3.5, 14), rng.uniform(0.2, 1.1, 14), strict=True
    ):
        eye = np.array(
            [
                np.cos(azimuth) * np.cos(elevation),
                np.sin(azimuth) * np.cos(elevation),
                np.sin(elevation),
            ]
        )
        c2w = look_at(4.0 * tilt @ eye + centre, centre, tilt @ np.array([0.0, 0.0, 1.0]))
        cameras.append(Camera(K, c2w, 16, 16))
    vertical = tilt @ np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(rig_vertical(cameras), vertical, atol=1e-12)
    frame = canonical_frame(cameras)
    # canonical +z
    np.testing.assert_allclose(frame.rotation @ vertical, [0.0, 0.0, 1.0], atol=1e-12)
    mean_up = -np.mean([c.c2w[:3, 1] for c in cameras], axis=0)
    # what the old rule took
    assert np.degrees(np.arccos(mean_up @ vertical / np.linalg.norm(mean_up))) > 5.0

    rolled = [
        dataclasses.replace(
            c,
            c2w=c.c2w
            @ np.block([[rotation([0, 0, 1], a), np.zeros((3, 1))], [np.zeros((1, 3)), 1.0]]),
        )
        for c, a in zip(cameras, rng.uniform(0, 2 * np.pi, len(cameras)), strict=True)
    ]
    forward = [
        Camera(
            K, np.block([[np.eye(3), np.array([[x], [y], [0.0]])], [np.zeros((1, 3)), 1.0]]), 16, 16
        )
        for x, y in ((0, 0), (1, 0), (0, 1), (1, 1.5))
    ]
    assert rig_vertical(rolled) is None and rig_vertical(forward) is None


def gaussian_method(name: str):
    from olatbench.methods.registry import get_spec

    module, attribute = get_spec(name).implementation.split(":")
    return getattr(__import__(module, fromlist=[attribute]), attribute)


@pytest.mark.parametrize("name", ["ssdgs", "gs3", "3dgs"])
def test_gaussian_methods_train_the_same_on_a_moved_scene(name):
    """Initial Gaussians, learning rates, density-control thresholds and three steps' losses are
    those of the original scene; in the dataset's own frame they are not."""
    cls = gaussian_method(name)
    extra = {"shadow_resolution": 32} if name == "ssdgs" else {}
    views = sphere_views(6, size=24)

    def trained(train: Views):
        method = cls(cls.resolve_config("mini", num_init_gaussians=300, **extra))
        method.setup(train, "cpu", 0)
        initial = method.model.means.detach().clone()
        losses = [method.train_step(step)["loss"] for step in range(3)]
        render = method.render(train.cameras[0], train.lights[0])["rgb"]
        return method, initial, losses, render

    original, initial, losses, render = trained(fitted(views))
    copy, copy_initial, copy_losses, copy_render = trained(fitted(moved(views)))
    torch.testing.assert_close(copy_initial, initial, rtol=1e-5, atol=1e-5)
    # extent-scaled: rounding
    assert copy.learning_rates(0) == pytest.approx(original.learning_rates(0), rel=1e-12)
    assert copy.densifier.config == original.densifier.config
    assert copy.train_views.scene_extent == pytest.approx(
        original.train_views.scene_extent, rel=1e-12
    )
    np.testing.assert_allclose(copy_losses, losses, rtol=1e-4)
    # render() takes world cameras and lights
    torch.testing.assert_close(copy_render, render, rtol=1e-3, atol=1e-3)
    # the world frame (no canonical frame): the moved copy starts its Gaussians elsewhere relative
    # to the scene
    _, _, world_losses, _ = trained(moved(views))
    assert not np.allclose(world_losses, losses, rtol=1e-3)


def test_checkpoint_refuses_another_frame():
    cls = gaussian_method("3dgs")
    views = fitted(sphere_views(4, size=16))
    method = cls(cls.resolve_config("mini", num_init_gaussians=50))
    method.setup(views, "cpu", 0)
    state = method.state_dict()
    other = cls(cls.resolve_config("mini", num_init_gaussians=50))
    other.setup(dataclasses.replace(views, frame=MOVE), "cpu", 0)
    with pytest.raises(ValueError, match="another canonical frame"):
        other.load_state_dict(state)
    same = cls(cls.resolve_config("mini", num_init_gaussians=50))
    same.setup(views, "cpu", 0)
    same.load_state_dict(state)


def test_sh_rotation_rotates_the_function():
    from olatbench.methods.baselines.sh import eval_sh, rotate_sh

    generator = torch.Generator().manual_seed(0)
    coefficients = torch.randn(4, 16, 3, generator=generator, dtype=torch.float64)
    rest = rotate_sh(coefficients[:, 1:], torch.as_tensor(MOVE.rotation))
    turned = torch.cat([coefficients[:, :1], rest], dim=1)
    dirs = torch.nn.functional.normalize(
        torch.randn(4, 3, generator=generator, dtype=torch.float64), dim=-1
    )
    moved_dirs = dirs @ torch.as_tensor(MOVE.rotation).T
    torch.testing.assert_close(eval_sh(3, turned, moved_dirs), eval_sh(3, coefficients, dirs))


def test_built_in_suites_keep_their_data_frame_and_other_suites_are_fitted(tmp_path):
    """The frame is decided per suite and recorded in the job; a job of a built-in suite keeps the
    id it had before the field existed (its identity has no ``frame``), and a job.json written
    before then reads as "dataset"."""
    from datasets_trees import write_nrhints_tree

    from olatbench.bench.jobs import Job
    from olatbench.bench.plan import make_plan
    from olatbench.datasets.suites import SUITES, data_suites

    assert {suite.frame for suite in SUITES.values()} == {"dataset"}
    write_nrhints_tree(tmp_path / "Cup", n_train=3, n_test=1, size=(16, 12))
    (suite,) = data_suites([tmp_path / "Cup"])
    assert suite.frame == "fitted"
    (job,) = make_plan("3dgs", suite, tmp_path / "runs", iterations=5, progress=False)
    assert job.frame == "fitted" and job.identity()["frame"] == "fitted"
    # the authors' code reads the files as they are: its jobs say so
    (official,) = make_plan(
        "gs3-official", suite, tmp_path / "runs", iterations=5, progress=False, generate=False
    )
    assert official.frame == "dataset"
    kept = dataclasses.replace(job, frame="dataset")
    assert "frame" not in kept.identity() and kept.with_id().id != job.id
    written = kept.with_id().to_json()
    del written["frame"]  # a job.json of an earlier version
    assert Job.from_json(written).frame == "dataset"
