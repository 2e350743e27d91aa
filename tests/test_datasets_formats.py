"""Readers: one test per format quirk listed in docs/datasets.md."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from datasets_trees import gl_look_at, write_gs3_tree, write_nrhints_tree, write_sssgs_tree

from olatbench.datasets import DatasetError, load_scene
from olatbench.datasets.cameras import project_points
from olatbench.datasets.formats import detect_format
from olatbench.datasets.images import write_image


def _edit(path: Path, change) -> None:
    meta = json.loads(path.read_text())
    change(meta)
    path.write_text(json.dumps(meta))


# --- detection ------------------------------------------------------------------------------------


def test_each_format_is_detected(tmp_path):
    write_nrhints_tree(tmp_path / "a")
    write_gs3_tree(tmp_path / "b")
    write_sssgs_tree(tmp_path / "c")
    assert [detect_format(tmp_path / n) for n in "abc"] == ["nrhints", "gs3", "sssgs"]
    assert [load_scene(tmp_path / n).format for n in "abc"] == ["nrhints", "gs3", "sssgs"]


def test_gs3_without_file_ext_is_detected_from_the_files(tmp_path):
    """The GS³ loader takes the extension from the command line; trees may omit ``file_ext``."""
    write_gs3_tree(tmp_path / "g")
    for name in ("transforms_train.json", "transforms_test.json"):
        _edit(tmp_path / "g" / name, lambda m: [f.pop("file_ext") for f in m["frames"]])
    scene = load_scene(tmp_path / "g")
    assert scene.format == "gs3" and scene.split("train")[0].image_path.suffix == ".exr"


def test_unknown_folder_is_a_clear_error(tmp_path):
    with pytest.raises(DatasetError, match="no known dataset format"):
        load_scene(tmp_path)


def test_explicit_format_overrides_detection(tmp_path):
    write_nrhints_tree(tmp_path / "a")
    assert load_scene(tmp_path / "a", format="nrhints").format == "nrhints"
    # forced GS³: default extension .exr
    with pytest.raises(DatasetError, match=r"000\.exr.*not found"):
        load_scene(tmp_path / "a", format="gs3")
    with pytest.raises(DatasetError, match="unknown format"):
        load_scene(tmp_path / "a", format="colmap")


# --- NRHints --------------------------------------------------------------------------------------


def test_nrhints_intrinsics_order_is_cx_cy_fx_fy(tmp_path):
    tree = write_nrhints_tree(tmp_path / "s", size=(16, 12))
    frame = load_scene(tmp_path / "s").split("train")[0]
    np.testing.assert_allclose(frame.camera.K, tree.frames["train"][0]["K"])
    assert (frame.camera.cx, frame.camera.cy, frame.camera.fx, frame.camera.fy) == (
        8.75,
        5.5,
        19.2,
        17.6,
    )


def test_nrhints_camera_angle_x_fallback(tmp_path):
    tree = write_nrhints_tree(tmp_path / "s", size=(16, 12), intrinsics=False)
    camera = load_scene(tmp_path / "s").split("train")[0].camera
    np.testing.assert_allclose(camera.K, tree.frames["train"][0]["K"])
    assert camera.fx == camera.fy and (camera.cx, camera.cy) == (8.0, 6.0)


def test_split_without_intrinsics_uses_the_train_split(tmp_path):
    """The NRHints parser reads intrinsics and near/far from the first split's file only."""
    tree = write_gs3_tree(tmp_path / "g")
    _edit(
        tmp_path / "g/transforms_test.json",
        lambda m: [m.pop(k) for k in ("camera_angle_x", "camera_near", "camera_far")],
    )
    camera = load_scene(tmp_path / "g").split("test")[0].camera
    np.testing.assert_allclose(camera.K, tree.frames["train"][0]["K"])
    assert (camera.near, camera.far) == (0.5, 20.0)


def test_transform_matrix_is_converted_once_to_opencv(tmp_path):
    """Cameras look at the origin: it must project onto the principal point, in front of the
    camera."""
    tree = write_nrhints_tree(tmp_path / "s")
    for frame, record in zip(
        load_scene(tmp_path / "s").split("train"), tree.frames["train"], strict=True
    ):
        uv, depth = project_points(np.zeros((1, 3)), frame.camera.K, frame.camera.c2w)
        np.testing.assert_allclose(uv[0], [frame.camera.cx, frame.camera.cy], atol=1e-9)
        assert depth[0] == pytest.approx(4.0)
        np.testing.assert_allclose(frame.camera.position, record["c2w_gl"][:3, 3])
        # world up (+z) appears upwards in the image: smaller pixel y
        uv_up, _ = project_points(np.array([[0.0, 0.0, 0.3]]), frame.camera.K, frame.camera.c2w)
        assert uv_up[0, 1] < frame.camera.cy


def test_file_path_without_extension_and_default_png(tmp_path):
    write_nrhints_tree(tmp_path / "s")
    meta = json.loads((tmp_path / "s/transforms_train.json").read_text())
    assert (
        not meta["frames"][0]["file_path"].endswith(".png") and "file_ext" not in meta["frames"][0]
    )
    assert load_scene(tmp_path / "s").split("train")[0].image_path.suffix == ".png"


def test_per_frame_file_ext_is_honoured(tmp_path):
    tree = write_nrhints_tree(tmp_path / "s")
    write_image(tmp_path / "s/train/000.tif", tree.frames["train"][0]["stored"], "uint8")
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][0].update(file_ext=".tif"))
    frame = load_scene(tmp_path / "s").split("train")[0]
    assert frame.image_path.name == "000.tif"
    np.testing.assert_allclose(
        frame.load(background=None).rgb, tree.frames["train"][0]["stored"][..., :3], atol=1e-6
    )


def test_npy_file_ext_is_read_as_the_nrhints_loader_reads_it(tmp_path):
    """data_parser.py:92-93 reads a ``file_ext: ".npy"`` frame with np.load
    (values as stored, no /255)."""
    tree = write_nrhints_tree(tmp_path / "s")
    stored = tree.frames["train"][1]["stored"]
    np.save(tmp_path / "s/train/001.npy", stored.astype(np.float32))
    (tmp_path / "s/train/001.png").unlink()
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][1].update(file_ext=".npy"))
    frame = load_scene(tmp_path / "s").split("train")[1]
    assert frame.image_path.name == "001.npy"
    np.testing.assert_allclose(frame.load(background=None).rgb, stored[..., :3], atol=1e-6)
    np.save(tmp_path / "s/train/001.npy", np.zeros((2, 2, 7), np.float32))
    with pytest.raises(DatasetError, match=r"001\.npy.*\(H, W, 1-4\)|\(H, W, 1-4\).*001\.npy"):
        load_scene(tmp_path / "s").split("train")[1].load()


def test_file_path_that_already_has_an_extension(tmp_path):
    write_nrhints_tree(tmp_path / "s")
    _edit(
        tmp_path / "s/transforms_train.json",
        lambda m: m["frames"][0].update(file_path="./train/000.png"),
    )
    assert load_scene(tmp_path / "s").split("train")[0].image_path.name == "000.png"


def test_gs3_img_path_is_preferred_over_file_path(tmp_path):
    """As the GS³ loader does: ``img_path`` (relative to the scene folder, extension included, no
    file_ext added) wins over ``file_path``, and names the frame."""
    tree = write_gs3_tree(tmp_path / "s", n_test=2)
    other = tree.frames["test"][1]["stored"]
    write_image(tmp_path / "s/renamed/view_07.exr", other, "half")
    _edit(
        tmp_path / "s/transforms_test.json",
        lambda m: m["frames"][0].update(img_path="renamed/view_07.exr"),
    )
    frame = load_scene(tmp_path / "s").split("test")[0]
    assert (
        frame.image_path == (tmp_path / "s/renamed/view_07.exr").resolve()
        and frame.frame_id == "view_07"
    )
    np.testing.assert_allclose(
        frame.load(background=None, colourspace="linear").rgb * other[..., 3:],
        other[..., :3],
        atol=2e-3,
    )


def test_nrhints_frames_with_only_img_path_are_detected_and_read(tmp_path):
    write_nrhints_tree(tmp_path / "s", n_train=2, n_test=1)

    def to_img_path(meta):
        for entry in meta["frames"]:
            entry["img_path"] = entry.pop("file_path").removeprefix("./") + ".png"

    for name in ("transforms_train.json", "transforms_test.json"):
        _edit(tmp_path / "s" / name, to_img_path)
    assert detect_format(tmp_path / "s") == "nrhints"
    scene = load_scene(tmp_path / "s")
    assert [f.image_path.name for f in scene.split("train")] == ["000.png", "001.png"]
    with pytest.raises(DatasetError, match="leaves the dataset root"):
        _edit(
            tmp_path / "s/transforms_test.json",
            lambda m: m["frames"][0].update(img_path="../outside.png"),
        )
        load_scene(tmp_path / "s")


def test_transforms_valid_is_a_camera_path_without_images(tmp_path):
    write_nrhints_tree(tmp_path / "s", n_path=3)
    scene = load_scene(tmp_path / "s")
    path = scene.split("path")
    assert len(path) == 3 and all(f.image_path is None for f in path)
    assert [f.frame_id for f in path] == ["path_0000", "path_0001", "path_0002"]
    with pytest.raises(DatasetError, match="no image"):
        path[0].load()


def test_val_split_is_read(tmp_path):
    write_nrhints_tree(tmp_path / "s", n_val=2)
    assert len(load_scene(tmp_path / "s").split("val")) == 2


def test_per_frame_lights(tmp_path):
    tree = write_nrhints_tree(tmp_path / "s")
    for frame, record in zip(
        load_scene(tmp_path / "s").split("train"), tree.frames["train"], strict=True
    ):
        np.testing.assert_array_equal(frame.light.position, record["pl_pos"])
        np.testing.assert_array_equal(frame.light.intensity, record["pl_intensity"])
        assert frame.light.intensity_known


def test_scalar_pl_intensity_is_broadcast_and_missing_is_unknown(tmp_path):
    write_nrhints_tree(tmp_path / "s", intensity=False)
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][0].update(pl_intensity=7.5))
    frames = load_scene(tmp_path / "s").split("train")
    np.testing.assert_array_equal(frames[0].light.intensity, [7.5, 7.5, 7.5])
    assert frames[0].light.intensity_known
    np.testing.assert_array_equal(frames[1].light.intensity, [1, 1, 1])
    assert not frames[1].light.intensity_known


@pytest.mark.parametrize(
    ("folder", "name"),
    [
        ("Cat_on_Decor", "CatSmall"),
        ("Cluttered", "FurScene"),
        ("Cup-Fabric", "CupFabric"),
        ("Pixiu", "Pixiu"),
    ],
)
def test_nrhints_folder_aliases(tmp_path, folder, name):
    write_nrhints_tree(tmp_path / folder, n_train=1, n_test=0)
    scene = load_scene(tmp_path / folder)
    assert scene.name == name and scene.metadata["folder"] == folder


def test_nrhints_png_is_srgb_straight_alpha_on_black(tmp_path):
    tree = write_nrhints_tree(tmp_path / "s")
    frame = load_scene(tmp_path / "s").split("train")[0]
    stored = tree.frames["train"][0]["stored"]
    assert frame.colourspace == "srgb" and frame.alpha_mode == "straight"
    np.testing.assert_allclose(frame.load().rgb, stored[..., :3] * stored[..., 3:], atol=1e-6)
    straight = frame.load(background=None)
    np.testing.assert_allclose(straight.rgb, stored[..., :3], atol=1e-6)
    np.testing.assert_allclose(straight.alpha, stored[..., 3], atol=1e-6)


def test_missing_pl_pos_is_an_error_not_the_origin(tmp_path):
    write_nrhints_tree(tmp_path / "s")
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][1].pop("pl_pos"))
    with pytest.raises(DatasetError, match="pl_pos") as error:
        load_scene(tmp_path / "s")
    assert error.value.frame == "001" and error.value.path.name == "transforms_train.json"


# --- GS³ ------------------------------------------------------------------------------------------


def test_gs3_exr_is_linear_premultiplied_on_white(tmp_path):
    tree = write_gs3_tree(tmp_path / "s")
    frame = load_scene(tmp_path / "s").split("train")[1]
    stored = tree.frames["train"][1]["stored"]
    rgb, alpha = stored[..., :3], stored[..., 3:]
    assert frame.colourspace == "linear" and frame.alpha_mode == "premultiplied"
    np.testing.assert_allclose(frame.load().rgb, rgb + (1 - alpha), atol=1e-6)
    straight = frame.load(background=None)
    inside = alpha[..., 0] > 0
    np.testing.assert_allclose(
        straight.rgb[inside], (rgb / np.maximum(alpha, 1e-8))[inside], rtol=1e-5
    )
    assert np.all(straight.rgb[~inside] == 0)


def test_gs3_near_far_and_fov(tmp_path):
    tree = write_gs3_tree(tmp_path / "s", size=(20, 10))
    camera = load_scene(tmp_path / "s").split("test")[0].camera
    assert (camera.near, camera.far, camera.width, camera.height) == (0.5, 20.0, 20, 10)
    np.testing.assert_allclose(camera.K, tree.frames["test"][0]["K"])


def test_gs3_per_frame_intrinsics_under_camera_angle_x_give_only_the_principal_point(tmp_path):
    """GS³'s reader (dataset_readers.py:105-106, 128-133, 168-174): with a top-level camera_angle_x
    the focal length is the angle's and only cx, cy come from the frame's camera_intrinsics."""
    write_gs3_tree(tmp_path / "s")
    _edit(
        tmp_path / "s/transforms_train.json",
        lambda m: m["frames"][2].update(camera_intrinsics=[7, 5, 30, 31]),
    )
    frames = load_scene(tmp_path / "s").split("train")
    focal = 0.5 * 16 / math.tan(0.5 * 0.69)
    camera = frames[2].camera
    assert (camera.cx, camera.cy) == (7, 5)
    assert camera.fx == pytest.approx(focal, rel=1e-12) and camera.fy == pytest.approx(
        focal, rel=1e-12
    )
    assert frames[1].camera.cx == 8.0


def test_gs3_per_frame_intrinsics_without_camera_angle_x_are_the_frames(tmp_path):
    write_gs3_tree(tmp_path / "s")

    def edit(meta):
        meta.pop("camera_angle_x")
        meta["camera_intrinsics"] = [8, 6, 20, 20]
        meta["frames"][-1]["camera_intrinsics"] = [7, 5, 30, 31]

    _edit(tmp_path / "s/transforms_train.json", edit)
    _edit(tmp_path / "s/transforms_test.json", edit)
    frames = load_scene(tmp_path / "s").split("train")
    assert (frames[3].camera.cx, frames[3].camera.cy, frames[3].camera.fx, frames[3].camera.fy) == (
        7,
        5,
        30,
        31,
    )
    assert (frames[1].camera.cx, frames[1].camera.fx) == (8, 20)


def test_top_level_precedence_follows_each_formats_reader(tmp_path):
    """Both camera_angle_x and camera_intrinsics at the top: GS³'s reader takes the angle
    (dataset_readers.py:105), NRHints' parser the intrinsics (data_parser.py:54)."""
    write_gs3_tree(tmp_path / "g")
    for name in ("transforms_train.json", "transforms_test.json"):
        _edit(tmp_path / "g" / name, lambda m: m.update(camera_intrinsics=[7, 5, 30, 31]))
    assert load_scene(tmp_path / "g").split("train")[0].camera.fx == pytest.approx(
        0.5 * 16 / math.tan(0.345)
    )
    write_nrhints_tree(tmp_path / "n")
    for name in ("transforms_train.json", "transforms_test.json"):
        _edit(tmp_path / "n" / name, lambda m: m.update(camera_angle_x=0.5))
    camera = load_scene(tmp_path / "n").split("train")[0].camera
    assert (camera.cx, camera.fx) == (16 / 2 + 0.75, 1.2 * 16)


def test_nrhints_frame_focal_that_contradicts_camera_angle_x_is_refused(tmp_path):
    write_nrhints_tree(tmp_path / "n", intrinsics=False)
    _edit(
        tmp_path / "n/transforms_train.json",
        lambda m: m["frames"][1].update(camera_intrinsics=[7, 5, 30, 31]),
    )
    with pytest.raises(
        DatasetError,
        match=r"transforms_train.json.*camera_intrinsics.*fx=30, fy=31 differ from the "
        r"focal length .* of the file's top-level camera_angle_x",
    ):
        load_scene(tmp_path / "n")


def test_gs3_refined_poses_are_the_camera_as_the_official_readers_take_them(tmp_path):
    """GS³/SSD-GS dataset_readers.py:135-148 use R_opt/T_opt instead of transform_matrix; so does
    olatbench, and a scene it writes says the same camera in both keys (an official and a native run
    of it see one camera)."""
    tree = write_gs3_tree(tmp_path / "s")
    frame = load_scene(tmp_path / "s").split("train")[0]
    R, T = np.eye(3), np.array([0.1, 0.2, 0.3])
    np.testing.assert_array_equal(frame.extras["T_opt"], T)
    np.testing.assert_array_equal(frame.extras["R_opt"], R)
    # 3DGS: centre = -(w2c rotation)ᵀ T, rotation = Rᵀ
    np.testing.assert_allclose(frame.camera.position, -R @ T)
    np.testing.assert_allclose(
        frame.extras["transform_matrix_c2w"][:3, 3], tree.frames["train"][0]["c2w_gl"][:3, 3]
    )
    from olatbench.datasets.convert import write_scene

    write_scene(load_scene(tmp_path / "s"), tmp_path / "out", "gs3")
    entry = json.loads((tmp_path / "out/transforms_train.json").read_text())["frames"][0]
    # what a reader of transform_matrix sees
    from_matrix = np.asarray(entry["transform_matrix"])[:3, 3]
    # what the official readers see
    from_opt = -np.asarray(entry["R_opt"]) @ np.asarray(entry["T_opt"])
    np.testing.assert_allclose(from_matrix, from_opt, atol=1e-12)
    again = load_scene(tmp_path / "out").split("train")[0]
    np.testing.assert_allclose(again.camera.c2w, frame.camera.c2w, atol=1e-12)


def test_gs3_r_opt_that_is_no_rotation_is_an_error(tmp_path):
    write_gs3_tree(tmp_path / "s")
    _edit(
        tmp_path / "s/transforms_train.json",
        lambda m: m["frames"][0].update(R_opt=np.full((3, 3), 0.5).tolist()),
    )
    with pytest.raises(DatasetError, match="R_opt is not a rotation"):
        load_scene(tmp_path / "s")


def test_gs3_r_opt_without_t_opt_is_an_error(tmp_path):
    write_gs3_tree(tmp_path / "s")
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][0].pop("T_opt"))
    with pytest.raises(DatasetError, match="T_opt"):
        load_scene(tmp_path / "s")


def test_gs3_path_split(tmp_path):
    write_gs3_tree(tmp_path / "s", n_path=2)
    assert [f.image_path for f in load_scene(tmp_path / "s").split("path")] == [None, None]


# --- SSS-GS ---------------------------------------------------------------------------------------


def test_sssgs_lists_expand_to_one_record_per_light(tmp_path):
    tree = write_sssgs_tree(tmp_path / "s", n_train_cameras=2, lights_per_camera=3)
    frames = load_scene(tmp_path / "s").split("train")
    assert len(frames) == 6
    for frame, record in zip(frames, tree.frames["train"], strict=True):
        assert frame.image_path == record["file"].resolve()
        np.testing.assert_allclose(frame.camera.position, record["c2w_gl"][:3, 3])


def test_sssgs_light_positions_are_used_as_stored(tmp_path):
    tree = write_sssgs_tree(tmp_path / "s")
    for frame, record in zip(
        load_scene(tmp_path / "s").split("train"), tree.frames["train"], strict=True
    ):
        np.testing.assert_array_equal(frame.light.position, record["pl_pos"])


def test_sssgs_per_frame_intrinsics_and_size(tmp_path):
    tree = write_sssgs_tree(tmp_path / "s", size=(16, 16))
    camera = load_scene(tmp_path / "s").split("test")[0].camera
    np.testing.assert_allclose(camera.K, tree.frames["test"][0]["K"])
    assert (camera.width, camera.height) == (16, 16)


def test_sssgs_camera_angle_x_alternative(tmp_path):
    write_sssgs_tree(tmp_path / "s", size=(16, 16))
    _edit(tmp_path / "s/transforms_train.json", lambda m: m.update(camera_angle_x=0.5))
    camera = load_scene(tmp_path / "s").split("train")[0].camera
    assert camera.fx == camera.fy == pytest.approx(8 / np.tan(0.25))


def test_sssgs_intensity_unknown_unless_given(tmp_path):
    write_sssgs_tree(tmp_path / "s", lights_per_camera=2)
    frame = load_scene(tmp_path / "s").split("train")[0]
    assert not frame.light.intensity_known and np.all(frame.light.intensity == 1)
    _edit(
        tmp_path / "s/transforms_train.json",
        lambda m: m["frames"][0].update(light_intensities=[2, [1, 2, 3]]),
    )
    frames = load_scene(tmp_path / "s").split("train")
    np.testing.assert_array_equal(frames[1].light.intensity, [1, 2, 3])
    assert frames[0].light.intensity_known


def test_sssgs_exclude_list(tmp_path):
    write_sssgs_tree(
        tmp_path / "s", n_train_cameras=2, lights_per_camera=3, excluded=("r_1_l_2.png", "r_0_l_0")
    )
    scene = load_scene(tmp_path / "s")
    ids = [f.frame_id for f in scene.split("train")]
    assert "r_1_l_2" not in ids and "r_0_l_0" not in ids and len(ids) == 4
    assert scene.metadata["excluded_images"] == 3  # r_0_l_0 is in train and in test
    assert len(scene.split("test")) == 2


def test_sssgs_shared_pngs_are_counted_and_ids_stay_unique(tmp_path):
    write_sssgs_tree(tmp_path / "s", share_first=True)
    scene = load_scene(tmp_path / "s")
    assert scene.metadata["shared_images"] == 1 and scene.metadata["shared_records"] == 2
    ids = [f.frame_id for f in scene.split("train")]
    assert len(set(ids)) == len(ids) and ids[:2] == ["r_0_l_0-1", "r_0_l_0-2"]


def test_sssgs_is_black_straight_srgb(tmp_path):
    tree = write_sssgs_tree(tmp_path / "s")
    frame = load_scene(tmp_path / "s").split("train")[0]
    stored = tree.frames["train"][0]["stored"]
    np.testing.assert_allclose(frame.load().rgb, stored[..., :3] * stored[..., 3:], atol=1e-6)


def test_gl_look_at_helper_is_a_rotation():
    c2w = gl_look_at([1.0, 2.0, 0.5])
    np.testing.assert_allclose(c2w[:3, :3].T @ c2w[:3, :3], np.eye(3), atol=1e-12)


def test_every_format_module_satisfies_the_format_protocol():
    import inspect

    from olatbench.datasets.formats import FORMATS, FormatModule

    members = [name for name in vars(FormatModule) if not name.startswith("_")]
    assert {"detect", "read_scene", "write_scene"} <= set(members)
    for name, module in FORMATS.items():
        assert name == module.FORMAT_NAME and isinstance(module.DISPLAY_COLOURSPACE, str)
        for member in members:
            # without self
            expected = list(inspect.signature(getattr(FormatModule, member)).parameters)[1:]
            found = list(inspect.signature(getattr(module, member)).parameters)
            assert found == expected, (
                f"format {name}: {member}{tuple(found)} != the protocol's {tuple(expected)}"
            )


def test_sssgs_reads_both_held_out_split_names(tmp_path):
    """The dataset card names ``transforms_eval.json``, other copies ``transforms_val.json``: both
    are read, as splits ``eval`` and ``val``; the suite itself trains on ``train`` and scores
    ``test``."""
    write_sssgs_tree(tmp_path / "bunny_small")
    test = json.loads((tmp_path / "bunny_small/transforms_test.json").read_text())
    (tmp_path / "bunny_small/transforms_eval.json").write_text(json.dumps(test))
    scene = load_scene(tmp_path / "bunny_small")
    assert len(scene.split("eval")) == len(scene.split("test")) == 3 and "val" not in scene.splits
    (tmp_path / "bunny_small/transforms_eval.json").rename(
        tmp_path / "bunny_small/transforms_val.json"
    )
    scene = load_scene(tmp_path / "bunny_small")
    assert len(scene.split("val")) == 3 and "eval" not in scene.splits
    from olatbench.datasets.suites import SUITES

    assert (SUITES["sssgs"].train_split, SUITES["sssgs"].test_split) == ("train", "test")


def scene_save(model: Path, source: Path, split: str, rng: np.random.Generator) -> list[dict]:
    """``transforms_<split>.json`` in ``model`` as GS³'s / SSD-GS's ``Scene.save`` writes it
    (scene/__init__.py :162-197 GS³, :164-199 SSD-GS): top-level ``camera_intrinsics``
    [cx, cy, fx, fy], per frame ``file_path`` (the image stem), the absolute ``img_path``, ``R_opt``
    (the camera-to-world rotation, OpenCV axes) / ``T_opt`` (the world-to-camera translation), the
    refined ``pl_pos`` and ``camera_intrinsics``; ``json.dump`` without indent. Returns the frames
    written (refined poses: random rotations and translations)."""
    meta = json.loads((source / f"transforms_{split}.json").read_text())
    frames = []
    for raw in meta["frames"]:
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        w, x, y, z = q
        R = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )
        image = (source / (raw["file_path"] + raw.get("file_ext", ".png"))).resolve()
        frames.append(
            {
                "file_path": image.stem,
                "img_path": str(image),
                "R_opt": R.tolist(),
                "T_opt": rng.normal(size=3).tolist(),
                "pl_pos": (np.asarray(raw["pl_pos"]) + 0.01).tolist(),
                "camera_intrinsics": [9.5, 5.5, 17.0, 17.5],
            }
        )
    model.mkdir(parents=True, exist_ok=True)
    with open(model / f"transforms_{split}.json", "w") as outfile:
        json.dump({"camera_intrinsics": [9.5, 5.5, 17.0, 17.5], "frames": frames}, outfile)
    return frames


@pytest.mark.parametrize("writer", [write_gs3_tree, write_nrhints_tree])
def test_scene_save_files_of_a_trained_model_are_read_with_their_refined_poses(tmp_path, writer):
    """A model folder's transforms files as the official Scene.save writes them: no
    transform_matrix, no pl_intensity, absolute img_path. Each frame's camera is the refined pose
    (world-to-camera [[R_optᵀ, T_opt]], dataset_readers.py:135-138), its light the refined pl_pos,
    its image the absolute path (reported)."""
    from click.testing import CliRunner

    from olatbench.cli import main

    writer(tmp_path / "data")
    model = tmp_path / "output" / "point_cloud" / "iteration_30000"
    rng = np.random.default_rng(3)
    written = {
        split: scene_save(model, tmp_path / "data", split, rng) for split in ("train", "test")
    }
    scene = load_scene(model)
    for split, frames in written.items():
        for frame, raw in zip(scene.split(split), frames, strict=True):
            w2c = np.eye(4)
            w2c[:3, :3], w2c[:3, 3] = np.asarray(raw["R_opt"]).T, raw["T_opt"]
            np.testing.assert_allclose(frame.camera.w2c(), w2c, atol=1e-12)
            np.testing.assert_allclose(frame.light.position, raw["pl_pos"])
            assert not frame.light.intensity_known
            assert (frame.camera.cx, frame.camera.cy, frame.camera.fx, frame.camera.fy) == (
                9.5,
                5.5,
                17.0,
                17.5,
            )
            assert frame.image_path == Path(raw["img_path"]) and frame.frame_id == raw["file_path"]
            assert frame.extras["absolute_img_path"] == raw["img_path"]
    assert scene.split("train")[0].load().rgb.shape[:2] == (12, 16)

    result = CliRunner().invoke(main, ["datasets", "info", str(model)])
    assert result.exit_code == 0, result.output
    out = result.output
    assert "6 frame(s) posed by their refined R_opt/T_opt" in out
    assert "6 read from outside the folder (absolute img_path" in out


def test_an_absolute_img_path_must_exist(tmp_path):
    write_nrhints_tree(tmp_path / "data")
    model = tmp_path / "model"
    scene_save(model, tmp_path / "data", "train", np.random.default_rng(0))
    scene_save(model, tmp_path / "data", "test", np.random.default_rng(1))
    missing = str((tmp_path / "elsewhere" / "gone.png").resolve())
    _edit(model / "transforms_test.json", lambda m: m["frames"][1].update(img_path=missing))
    with pytest.raises(
        DatasetError,
        match=r"transforms_test.json.*img_path.*absolute image path '.*gone.png' does "
        r"not exist",
    ) as error:
        load_scene(model)
    assert error.value.key == "img_path"


def test_nrhints_background_is_the_one_nrhints_trains_the_scene_on(tmp_path):
    """NRHints trains synthetic (Blender: camera_angle_x, no camera_intrinsics) scenes on white
    (scripts/train_synthetic.sh) and real captures (camera_intrinsics) on black
    (scripts/train_real.sh); a scene olatbench generated (synth.json) keeps the black it was
    rendered on. `datasets info` says which and why."""
    from click.testing import CliRunner

    from olatbench.cli import main

    write_nrhints_tree(tmp_path / "synthetic", intrinsics=False)
    write_nrhints_tree(tmp_path / "real")
    write_nrhints_tree(tmp_path / "generated", intrinsics=False)
    (tmp_path / "generated" / "synth.json").write_text("{}")
    synthetic = load_scene(tmp_path / "synthetic")
    assert synthetic.background.tolist() == [1.0, 1.0, 1.0]
    assert all(f.background.tolist() == [1.0, 1.0, 1.0] for f in synthetic)
    assert synthetic.metadata["background"].startswith("white (NRHints synthetic scene")
    for name in ("real", "generated"):
        scene = load_scene(tmp_path / name)
        assert scene.background.tolist() == [0.0, 0.0, 0.0] and all(
            f.background.tolist() == [0, 0, 0] for f in scene
        )
    assert "train_real.sh" in load_scene(tmp_path / "real").metadata["background"]
    assert "synth.json" in load_scene(tmp_path / "generated").metadata["background"]
    result = CliRunner().invoke(main, ["datasets", "info", str(tmp_path / "synthetic")])
    assert result.exit_code == 0, result.output
    assert "background [1.0, 1.0, 1.0]" in result.output
    assert (
        "background=white (NRHints synthetic scene: camera_angle_x, no camera_intrinsics"
        in result.output
    )
