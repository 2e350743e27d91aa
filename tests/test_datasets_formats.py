"""Readers: one test per format quirk listed in docs/datasets.md."""

from __future__ import annotations

import json
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


# --- detection -------------------------------------------------------------------------------------------

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
    with pytest.raises(DatasetError, match=r"000\.exr.*not found"):  # forced GS³: default extension .exr
        load_scene(tmp_path / "a", format="gs3")
    with pytest.raises(DatasetError, match="unknown format"):
        load_scene(tmp_path / "a", format="colmap")


# --- NRHints ---------------------------------------------------------------------------------------------

def test_nrhints_intrinsics_order_is_cx_cy_fx_fy(tmp_path):
    tree = write_nrhints_tree(tmp_path / "s", size=(16, 12))
    frame = load_scene(tmp_path / "s").split("train")[0]
    np.testing.assert_allclose(frame.camera.K, tree.frames["train"][0]["K"])
    assert (frame.camera.cx, frame.camera.cy, frame.camera.fx, frame.camera.fy) == (8.75, 5.5, 19.2, 17.6)


def test_nrhints_camera_angle_x_fallback(tmp_path):
    tree = write_nrhints_tree(tmp_path / "s", size=(16, 12), intrinsics=False)
    camera = load_scene(tmp_path / "s").split("train")[0].camera
    np.testing.assert_allclose(camera.K, tree.frames["train"][0]["K"])
    assert camera.fx == camera.fy and (camera.cx, camera.cy) == (8.0, 6.0)


def test_split_without_intrinsics_uses_the_train_split(tmp_path):
    """The NRHints parser reads intrinsics and near/far from the first split's file only."""
    tree = write_gs3_tree(tmp_path / "g")
    _edit(tmp_path / "g/transforms_test.json", lambda m: [m.pop(k) for k in ("camera_angle_x", "camera_near",
                                                                              "camera_far")])
    camera = load_scene(tmp_path / "g").split("test")[0].camera
    np.testing.assert_allclose(camera.K, tree.frames["train"][0]["K"])
    assert (camera.near, camera.far) == (0.5, 20.0)


def test_transform_matrix_is_converted_once_to_opencv(tmp_path):
    """Cameras look at the origin: it must project onto the principal point, in front of the camera."""
    tree = write_nrhints_tree(tmp_path / "s")
    for frame, record in zip(load_scene(tmp_path / "s").split("train"), tree.frames["train"], strict=True):
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
    assert not meta["frames"][0]["file_path"].endswith(".png") and "file_ext" not in meta["frames"][0]
    assert load_scene(tmp_path / "s").split("train")[0].image_path.suffix == ".png"


def test_per_frame_file_ext_is_honoured(tmp_path):
    tree = write_nrhints_tree(tmp_path / "s")
    write_image(tmp_path / "s/train/000.tif", tree.frames["train"][0]["stored"], "uint8")
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][0].update(file_ext=".tif"))
    frame = load_scene(tmp_path / "s").split("train")[0]
    assert frame.image_path.name == "000.tif"
    np.testing.assert_allclose(frame.load(background=None).rgb, tree.frames["train"][0]["stored"][..., :3], atol=1e-6)


def test_npy_file_ext_is_read_as_the_nrhints_loader_reads_it(tmp_path):
    """data_parser.py:92-93 reads a ``file_ext: ".npy"`` frame with np.load (values as stored, no /255)."""
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
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][0].update(file_path="./train/000.png"))
    assert load_scene(tmp_path / "s").split("train")[0].image_path.name == "000.png"


def test_gs3_img_path_is_preferred_over_file_path(tmp_path):
    """As the GS³ loader does: ``img_path`` (relative to the scene folder, extension included, no file_ext added)
    wins over ``file_path``, and names the frame."""
    tree = write_gs3_tree(tmp_path / "s", n_test=2)
    other = tree.frames["test"][1]["stored"]
    write_image(tmp_path / "s/renamed/view_07.exr", other, "half")
    _edit(tmp_path / "s/transforms_test.json", lambda m: m["frames"][0].update(img_path="renamed/view_07.exr"))
    frame = load_scene(tmp_path / "s").split("test")[0]
    assert frame.image_path == (tmp_path / "s/renamed/view_07.exr").resolve() and frame.frame_id == "view_07"
    np.testing.assert_allclose(frame.load(background=None, colourspace="linear").rgb * other[..., 3:],
                               other[..., :3], atol=2e-3)


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
        _edit(tmp_path / "s/transforms_test.json", lambda m: m["frames"][0].update(img_path="../outside.png"))
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
    for frame, record in zip(load_scene(tmp_path / "s").split("train"), tree.frames["train"], strict=True):
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


@pytest.mark.parametrize(("folder", "name"), [("Cat_on_Decor", "CatSmall"), ("Cluttered", "FurScene"),
                                              ("Cup-Fabric", "CupFabric"), ("Pixiu", "Pixiu")])
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


# --- GS³ -------------------------------------------------------------------------------------------------

def test_gs3_exr_is_linear_premultiplied_on_white(tmp_path):
    tree = write_gs3_tree(tmp_path / "s")
    frame = load_scene(tmp_path / "s").split("train")[1]
    stored = tree.frames["train"][1]["stored"]
    rgb, alpha = stored[..., :3], stored[..., 3:]
    assert frame.colourspace == "linear" and frame.alpha_mode == "premultiplied"
    np.testing.assert_allclose(frame.load().rgb, rgb + (1 - alpha), atol=1e-6)
    straight = frame.load(background=None)
    inside = alpha[..., 0] > 0
    np.testing.assert_allclose(straight.rgb[inside], (rgb / np.maximum(alpha, 1e-8))[inside], rtol=1e-5)
    assert np.all(straight.rgb[~inside] == 0)


def test_gs3_near_far_and_fov(tmp_path):
    tree = write_gs3_tree(tmp_path / "s", size=(20, 10))
    camera = load_scene(tmp_path / "s").split("test")[0].camera
    assert (camera.near, camera.far, camera.width, camera.height) == (0.5, 20.0, 20, 10)
    np.testing.assert_allclose(camera.K, tree.frames["test"][0]["K"])


def test_gs3_per_frame_intrinsics_override(tmp_path):
    write_gs3_tree(tmp_path / "s")
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][2].update(camera_intrinsics=[7, 5, 30, 31]))
    frames = load_scene(tmp_path / "s").split("train")
    assert (frames[2].camera.cx, frames[2].camera.cy, frames[2].camera.fx, frames[2].camera.fy) == (7, 5, 30, 31)
    assert frames[1].camera.cx == 8.0


def test_gs3_refined_poses_are_the_camera_as_the_official_readers_take_them(tmp_path):
    """GS³/SSD-GS dataset_readers.py:135-148 use R_opt/T_opt instead of transform_matrix; so does olatbench, and a
    scene it writes says the same camera in both keys (an official and a native run of it see one camera)."""
    tree = write_gs3_tree(tmp_path / "s")
    frame = load_scene(tmp_path / "s").split("train")[0]
    R, T = np.eye(3), np.array([0.1, 0.2, 0.3])
    np.testing.assert_array_equal(frame.extras["T_opt"], T)
    np.testing.assert_array_equal(frame.extras["R_opt"], R)
    np.testing.assert_allclose(frame.camera.position, -R @ T)  # 3DGS: centre = -(w2c rotation)ᵀ T, rotation = Rᵀ
    np.testing.assert_allclose(frame.extras["transform_matrix_c2w"][:3, 3], tree.frames["train"][0]["c2w_gl"][:3, 3])
    from olatbench.datasets.convert import write_scene

    write_scene(load_scene(tmp_path / "s"), tmp_path / "out", "gs3")
    entry = json.loads((tmp_path / "out/transforms_train.json").read_text())["frames"][0]
    from_matrix = np.asarray(entry["transform_matrix"])[:3, 3]  # what a reader of transform_matrix sees
    from_opt = -np.asarray(entry["R_opt"]) @ np.asarray(entry["T_opt"])  # what the official readers see
    np.testing.assert_allclose(from_matrix, from_opt, atol=1e-12)
    again = load_scene(tmp_path / "out").split("train")[0]
    np.testing.assert_allclose(again.camera.c2w, frame.camera.c2w, atol=1e-12)


def test_gs3_r_opt_that_is_no_rotation_is_an_error(tmp_path):
    write_gs3_tree(tmp_path / "s")
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][0].update(R_opt=np.full((3, 3), 0.5).tolist()))
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


# --- SSS-GS ----------------------------------------------------------------------------------------------

def test_sssgs_lists_expand_to_one_record_per_light(tmp_path):
    tree = write_sssgs_tree(tmp_path / "s", n_train_cameras=2, lights_per_camera=3)
    frames = load_scene(tmp_path / "s").split("train")
    assert len(frames) == 6
    for frame, record in zip(frames, tree.frames["train"], strict=True):
        assert frame.image_path == record["file"].resolve()
        np.testing.assert_allclose(frame.camera.position, record["c2w_gl"][:3, 3])


def test_sssgs_light_positions_are_used_as_stored(tmp_path):
    tree = write_sssgs_tree(tmp_path / "s")
    for frame, record in zip(load_scene(tmp_path / "s").split("train"), tree.frames["train"], strict=True):
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
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][0].update(light_intensities=[2, [1, 2, 3]]))
    frames = load_scene(tmp_path / "s").split("train")
    np.testing.assert_array_equal(frames[1].light.intensity, [1, 2, 3])
    assert frames[0].light.intensity_known


def test_sssgs_exclude_list(tmp_path):
    write_sssgs_tree(tmp_path / "s", n_train_cameras=2, lights_per_camera=3, excluded=("r_1_l_2.png", "r_0_l_0"))
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
            expected = list(inspect.signature(getattr(FormatModule, member)).parameters)[1:]  # without self
            found = list(inspect.signature(getattr(module, member)).parameters)
            assert found == expected, f"format {name}: {member}{tuple(found)} != the protocol's {tuple(expected)}"


def test_sssgs_reads_both_held_out_split_names(tmp_path):
    """The dataset card names ``transforms_eval.json``, other copies ``transforms_val.json``: both are read, as
    splits ``eval`` and ``val``; the suite itself trains on ``train`` and scores ``test``."""
    write_sssgs_tree(tmp_path / "bunny_small")
    test = json.loads((tmp_path / "bunny_small/transforms_test.json").read_text())
    (tmp_path / "bunny_small/transforms_eval.json").write_text(json.dumps(test))
    scene = load_scene(tmp_path / "bunny_small")
    assert len(scene.split("eval")) == len(scene.split("test")) == 3 and "val" not in scene.splits
    (tmp_path / "bunny_small/transforms_eval.json").rename(tmp_path / "bunny_small/transforms_val.json")
    scene = load_scene(tmp_path / "bunny_small")
    assert len(scene.split("val")) == 3 and "eval" not in scene.splits
    from olatbench.datasets.suites import SUITES

    assert (SUITES["sssgs"].train_split, SUITES["sssgs"].test_split) == ("train", "test")
