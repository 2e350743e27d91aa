"""Round trips through write_scene: cameras, lights and pixels within quantisation."""

from __future__ import annotations

import numpy as np
import pytest
from datasets_trees import write_gs3_tree, write_nrhints_tree, write_sssgs_tree

from olatbench.datasets import Camera, DatasetError, Frame, PointLight, Scene, load_scene
from olatbench.datasets.cameras import intrinsics_matrix, look_at
from olatbench.datasets.convert import frame_pixels, write_scene

WRITERS = {"nrhints": write_nrhints_tree, "gs3": write_gs3_tree, "sssgs": write_sssgs_tree}
# worst pixel error of linear straight colour after one trip through the target's encoding
LINEAR_TOLERANCE = {"nrhints": 1 / 255 * 1.0, "sssgs": 1 / 255 * 1.0, "gs3": 2e-3}


def _assert_same_geometry(a: Frame, b: Frame) -> None:
    np.testing.assert_allclose(b.camera.c2w, a.camera.c2w, atol=1e-12)
    np.testing.assert_allclose(b.camera.K, a.camera.K, atol=1e-9)
    assert (b.camera.width, b.camera.height) == (a.camera.width, a.camera.height)
    np.testing.assert_array_equal(b.light.position, a.light.position)
    np.testing.assert_array_equal(b.light.intensity, a.light.intensity)
    assert b.light.intensity_known == a.light.intensity_known


def _straight_srgb(frame: Frame) -> tuple[np.ndarray, np.ndarray]:
    """Straight sRGB colour clipped to 1 (PNG targets cannot hold HDR), and alpha.

    Compared instead of a composite because the formats composite in different spaces
    (sRGB for PNGs, linear for EXRs), which legitimately differs at fractional alpha.
    """
    image = frame.load(colourspace="srgb", background=None)
    return np.clip(image.rgb, 0.0, 1.0), image.alpha


@pytest.mark.parametrize("source", ["nrhints", "gs3", "sssgs"])
@pytest.mark.parametrize("target", ["nrhints", "gs3", "sssgs"])
def test_round_trip(tmp_path, source, target):
    WRITERS[source](tmp_path / "src")
    scene = load_scene(tmp_path / "src")
    out = write_scene(scene, tmp_path / "out", target)
    back = load_scene(out)
    assert back.format == target
    assert {s: len(f) for s, f in back.frames.items()} == {
        s: len(f) for s, f in scene.frames.items()
    }
    for split in scene.splits:
        for a, b in zip(scene.split(split), back.split(split), strict=True):
            _assert_same_geometry(a, b)
            rgb_a, alpha_a = _straight_srgb(a)
            rgb_b, alpha_b = _straight_srgb(b)
            # 8-bit targets: half a code value; half-float EXR: relative 2^-11, amplified by 1/alpha
            # on unpremultiply
            np.testing.assert_allclose(
                alpha_b, alpha_a, atol=0.5 / 255 + 1e-6 if target != "gs3" else 1e-3
            )
            seen = alpha_a > 0.1
            if "gs3" in (source, target):
                np.testing.assert_allclose(
                    rgb_b[seen], rgb_a[seen], atol=0.5 / 255 + 1e-5, rtol=1e-2
                )
            else:
                np.testing.assert_allclose(rgb_b[seen], rgb_a[seen], atol=0.5 / 255 + 1e-5)


def test_same_format_round_trip_is_exact_for_pngs(tmp_path):
    write_nrhints_tree(tmp_path / "src")
    scene = load_scene(tmp_path / "src")
    back = load_scene(write_scene(scene, tmp_path / "out", "nrhints"))
    for a, b in zip(scene.split("train"), back.split("train"), strict=True):
        np.testing.assert_array_equal(b.load(background=None).rgb, a.load(background=None).rgb)


def test_gs3_hdr_survives_a_gs3_round_trip(tmp_path):
    write_gs3_tree(tmp_path / "src")
    scene = load_scene(tmp_path / "src")
    back = load_scene(write_scene(scene, tmp_path / "out", "gs3"))
    a, b = scene.split("train")[1].load(), back.split("train")[1].load()
    assert a.rgb.max() > 1.5
    np.testing.assert_allclose(b.rgb, a.rgb, rtol=2e-3, atol=1e-4)


def test_path_split_refined_poses_and_near_far_survive(tmp_path):
    write_gs3_tree(tmp_path / "src", n_path=3)
    scene = load_scene(tmp_path / "src")
    back = load_scene(write_scene(scene, tmp_path / "out", "nrhints"))
    assert [f.image_path for f in back.split("path")] == [None] * 3
    for a, b in zip(scene.split("path"), back.split("path"), strict=True):
        _assert_same_geometry(a, b)
    np.testing.assert_array_equal(back.split("train")[0].extras["T_opt"], [0.1, 0.2, 0.3])
    assert back.split("train")[0].camera.near == 0.5 and back.split("train")[0].camera.far == 20.0


def test_sssgs_writer_groups_lights_per_camera_and_keeps_shared_files(tmp_path):
    write_sssgs_tree(tmp_path / "src", n_train_cameras=2, lights_per_camera=3, share_first=True)
    scene = load_scene(tmp_path / "src")
    out = write_scene(scene, tmp_path / "out", "sssgs")
    import json

    meta = json.loads((out / "transforms_train.json").read_text())
    assert [len(f["file_paths"]) for f in meta["frames"]] == [3, 3]
    assert meta["frames"][0]["file_paths"][0] == meta["frames"][0]["file_paths"][1]
    assert load_scene(out).metadata["shared_images"] == 1


def test_off_centre_intrinsics_are_written_as_camera_intrinsics(tmp_path):
    write_nrhints_tree(tmp_path / "src")
    out = write_scene(load_scene(tmp_path / "src"), tmp_path / "out", "gs3")
    import json

    assert json.loads((out / "transforms_train.json").read_text())["camera_intrinsics"] == [
        8.75,
        5.5,
        19.2,
        17.6,
    ]


def _generated_scene(root, n=3, size=(10, 8)) -> Scene:
    width, height = size
    K = intrinsics_matrix(12.0, 12.0, width / 2, height / 2)
    frames = [
        Frame(
            scene="gen",
            split="train",
            frame_id=f"g{i}",
            image_path=None,
            camera=Camera(
                K=K, c2w=look_at([3.0, float(i), 1.0], [0, 0, 0]), width=width, height=height
            ),
            light=PointLight(
                position=np.array([0.0, 4.0, float(i)]),
                intensity=np.full(3, 9.0),
                intensity_known=True,
            ),
        )
        for i in range(n)
    ]
    return Scene(name="gen", format="synthetic", root=root, frames={"train": frames})


@pytest.mark.parametrize("target", ["nrhints", "gs3", "sssgs"])
def test_generated_frames_with_pixels_callable(tmp_path, target):
    """The scene generator's path: frames without files, pixels as linear straight RGBA."""
    scene = _generated_scene(tmp_path / "nowhere")
    rng = np.random.default_rng(1)
    images = {
        f.frame_id: rng.uniform(0, 1, (8, 10, 4)).astype(np.float32) for f in scene.split("train")
    }
    back = load_scene(write_scene(scene, tmp_path / "out", target, lambda f: images[f.frame_id]))
    for frame in back.split("train"):
        loaded = frame.load(colourspace="linear", background=None)
        expected = images[frame.frame_id]
        tolerance = 2e-3 if target == "gs3" else 0.01  # 8-bit sRGB steps are ≤ 0.0085 in linear
        mask = expected[..., 3] > 0.05 if target == "gs3" else np.ones(expected.shape[:2], bool)
        np.testing.assert_allclose(
            loaded.rgb[mask], expected[..., :3][mask], atol=tolerance, rtol=0.02
        )
        np.testing.assert_allclose(loaded.alpha, expected[..., 3], atol=2e-3)


def test_frames_without_images_need_pixels(tmp_path):
    with pytest.raises(DatasetError, match="pass pixels="):
        write_scene(_generated_scene(tmp_path), tmp_path / "out", "nrhints")


@pytest.mark.parametrize(
    ("bad", "message"), [(np.zeros((8, 10, 3)), "expected"), (np.full((8, 10, 4), np.nan), "NaN")]
)
def test_bad_pixels_are_refused(tmp_path, bad, message):
    with pytest.raises(DatasetError, match=message):
        write_scene(_generated_scene(tmp_path), tmp_path / "out", "nrhints", lambda f: bad)


def test_refuses_to_overwrite_or_write_into_the_source(tmp_path):
    write_nrhints_tree(tmp_path / "src")
    scene = load_scene(tmp_path / "src")
    with pytest.raises(DatasetError, match="inside the source"):
        write_scene(scene, tmp_path / "src" / "converted", "gs3")
    write_scene(scene, tmp_path / "out", "gs3")
    with pytest.raises(DatasetError, match="already exists"):
        write_scene(scene, tmp_path / "out", "gs3")
    write_scene(scene, tmp_path / "out", "gs3", overwrite=True)


def test_unknown_target_format(tmp_path):
    write_nrhints_tree(tmp_path / "src")
    with pytest.raises(DatasetError, match="unknown format"):
        write_scene(load_scene(tmp_path / "src"), tmp_path / "out", "colmap")


def test_frame_pixels_is_linear_straight(tmp_path):
    tree = write_nrhints_tree(tmp_path / "src")
    frame = load_scene(tmp_path / "src").split("train")[0]
    rgba = frame_pixels(frame)
    stored = tree.frames["train"][0]["stored"]
    from olatbench.datasets.colour import srgb_to_linear

    np.testing.assert_allclose(rgba[..., :3], srgb_to_linear(stored[..., :3]), atol=1e-6)
    np.testing.assert_allclose(rgba[..., 3], stored[..., 3], atol=1e-6)


def test_named_channels_round_trip(tmp_path):
    from olatbench.datasets.images import read_channels, write_image

    planes = np.random.default_rng(0).random((5, 7, 3)).astype(np.float32)
    write_image(tmp_path / "aov.exr", planes, "float", channel_names=["A", "N.X", "Z"])
    channels = read_channels(tmp_path / "aov.exr")
    # EXR stores channels in its own order: names are the contract
    assert sorted(channels) == ["A", "N.X", "Z"]
    for index, name in enumerate(["A", "N.X", "Z"]):
        np.testing.assert_array_equal(channels[name], planes[..., index])
