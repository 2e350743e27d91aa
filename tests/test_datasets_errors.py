"""Bad input: every problem is one DatasetError naming the file, the frame and the key."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from datasets_trees import write_gs3_tree, write_nrhints_tree, write_sssgs_tree

from olatbench.datasets import DatasetError, load_scene
from olatbench.datasets.images import write_image
from olatbench.datasets.validate import validate_folder


def _edit(path: Path, change) -> None:
    meta = json.loads(path.read_text())
    change(meta)
    path.write_text(json.dumps(meta))


@pytest.fixture
def nrhints(tmp_path):
    write_nrhints_tree(tmp_path / "s")
    return tmp_path / "s"


def test_malformed_json(nrhints):
    (nrhints / "transforms_test.json").write_text('{"frames": [1, 2,')
    with pytest.raises(DatasetError, match=r"transforms_test\.json: malformed JSON \(line 1"):
        load_scene(nrhints)


def test_top_level_not_an_object_and_frames_not_a_list(nrhints):
    (nrhints / "transforms_test.json").write_text("[]")
    with pytest.raises(DatasetError, match="JSON object"):
        load_scene(nrhints)
    (nrhints / "transforms_test.json").write_text('{"frames": 3}')
    with pytest.raises(DatasetError, match="key 'frames'"):
        load_scene(nrhints)


def test_missing_transform_matrix_names_frame_and_key(nrhints):
    _edit(nrhints / "transforms_test.json", lambda m: m["frames"][1].pop("transform_matrix"))
    with pytest.raises(DatasetError) as error:
        load_scene(nrhints)
    assert (error.value.frame, error.value.key, error.value.path.name) == (
        "001",
        "transform_matrix",
        "transforms_test.json",
    )


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("pl_pos", [0.0, float("nan"), 1.0]),
        ("pl_intensity", [1.0, float("inf"), 1.0]),
        ("transform_matrix", [[float("nan")] * 4] * 4),
    ],
)
def test_nan_and_inf_are_refused(nrhints, key, value):
    _edit(nrhints / "transforms_train.json", lambda m: m["frames"][2].update({key: value}))
    with pytest.raises(DatasetError, match="NaN or Inf") as error:
        load_scene(nrhints)
    assert error.value.key == key and error.value.frame == "002"


def test_wrong_shapes(nrhints):
    _edit(nrhints / "transforms_train.json", lambda m: m["frames"][0].update(pl_pos=[1, 2]))
    with pytest.raises(DatasetError, match=r"expected shape \(3,\)"):
        load_scene(nrhints)


def test_bad_intrinsics(nrhints):
    _edit(nrhints / "transforms_train.json", lambda m: m.update(camera_intrinsics=[8, 6, 0, 10]))
    with pytest.raises(DatasetError, match="camera_intrinsics"):
        load_scene(nrhints)


def test_no_intrinsics_at_all(nrhints):
    _edit(nrhints / "transforms_train.json", lambda m: m.pop("camera_intrinsics"))
    with pytest.raises(DatasetError, match="no intrinsics"):
        load_scene(nrhints)


@pytest.mark.parametrize("escape", ["../../outside", "/etc/passwd", "train/../../outside"])
def test_file_path_escaping_the_root(nrhints, escape):
    _edit(nrhints / "transforms_test.json", lambda m: m["frames"][0].update(file_path=escape))
    with pytest.raises(DatasetError, match="leaves the dataset root") as error:
        load_scene(nrhints)
    assert error.value.key == "file_path"


def test_a_folder_the_user_linked_elsewhere_is_followed(nrhints, tmp_path):
    """#38 item 14: ``train/`` moved to another disk and linked back is the user's to make; only a
    path written in a transforms file must not leave the root."""
    other_disk = tmp_path / "other_disk"
    (nrhints / "train").rename(other_disk)
    os.symlink(other_disk, nrhints / "train")
    scene = load_scene(nrhints)
    assert scene.split("train")[0].load().rgb.shape[:2] == (12, 16)
    assert validate_folder(nrhints).ok
    _edit(
        nrhints / "transforms_test.json",
        lambda m: m["frames"][0].update(file_path="train/../../other_disk/000"),
    )
    with pytest.raises(DatasetError, match="leaves the dataset root"):
        load_scene(nrhints)


@pytest.mark.parametrize("split_file", ["transforms_train.json", "transforms_test.json"])
@pytest.mark.parametrize("damage", ["folder", "loop", "dangling"])
def test_a_split_file_that_is_no_file_is_an_error_not_a_missing_split(nrhints, split_file, damage):
    """#38 item 10: a transforms file replaced by a folder, a link loop or a dangling link fails the
    scene."""
    path = nrhints / split_file
    path.unlink()
    if damage == "folder":
        path.mkdir()
    else:
        os.symlink(path.name if damage == "loop" else "gone.json", path)
    expected = {
        "folder": "is a folder",
        "loop": "symbolic link loop",
        "dangling": "link to a missing file",
    }[damage]
    with pytest.raises(DatasetError, match=expected) as error:
        load_scene(nrhints)
    assert error.value.path == path
    report = validate_folder(nrhints)
    assert not report.ok and [issue.path for issue in report.errors] == [str(path)]


def test_an_empty_frame_list_is_an_error(nrhints):
    """#38 item 10: ``"frames": []`` is a file describing nothing, not a valid empty split."""
    _edit(nrhints / "transforms_test.json", lambda m: m.update(frames=[]))
    with pytest.raises(DatasetError, match="empty list") as error:
        load_scene(nrhints)
    assert (error.value.path.name, error.value.key) == ("transforms_test.json", "frames")
    assert [issue.key for issue in validate_folder(nrhints).errors] == ["frames"]


def test_an_image_that_is_a_link_loop_is_one_error(nrhints):
    """#38 item 9: a link loop is named as such (Path.resolve raised RuntimeError before)."""
    image = nrhints / "test/001.png"
    image.unlink()
    os.symlink(image.name, image)
    with pytest.raises(DatasetError, match="symbolic link loop") as error:
        load_scene(nrhints).split("test")[1].load()
    assert (error.value.path, error.value.frame) == (image, "001")
    (issue,) = validate_folder(nrhints).errors
    assert (issue.path, issue.frame) == (
        str(image),
        "001",
    ) and "symbolic link loop" in issue.message


def test_a_name_that_is_not_utf8_is_one_error(tmp_path):
    """#38 item 9: OpenImageIO takes UTF-8 names only (it raised TypeError); the error shows the
    byte as \\xff."""
    write_nrhints_tree(tmp_path / "s")
    root = Path(os.fsdecode(os.fsencode(tmp_path / "s") + b"\xff"))
    (tmp_path / "s").rename(root)
    with pytest.raises(DatasetError, match="not valid UTF-8") as error:
        load_scene(root)
    assert error.value.path == root / "train/000.png" and "s\\xff" in str(error.value)
    assert not validate_folder(root).ok


def test_missing_image(nrhints):
    (nrhints / "test/001.png").unlink()
    scene = load_scene(nrhints)  # reading the JSON does not decode images
    with pytest.raises(DatasetError, match="not found") as error:
        scene.split("test")[1].load()
    assert error.value.path.name == "001.png"
    report = validate_folder(nrhints)
    assert not report.ok and any(
        "not found" in issue.message and issue.frame == "001" for issue in report.issues
    )


def test_missing_first_image_needed_for_size(nrhints):
    (nrhints / "train/000.png").unlink()
    with pytest.raises(DatasetError, match=r"000\.png.*needed for the image size"):
        load_scene(nrhints)


@pytest.mark.parametrize("damage", ["truncate", "garbage"])
def test_corrupt_or_truncated_image(nrhints, damage):
    image = nrhints / "test/000.png"
    data = image.read_bytes()
    image.write_bytes(
        data[: len(data) // 2] if damage == "truncate" else b"\x89PNG not really" + bytes(100)
    )
    frame = load_scene(nrhints).split("test")[0]
    with pytest.raises(DatasetError) as error:
        frame.load()
    assert error.value.path.name == "000.png" and error.value.frame == "000"
    assert not validate_folder(nrhints).ok


def test_mismatched_resolution(nrhints):
    write_image(nrhints / "test/001.png", np.zeros((6, 8, 4)), "uint8")
    frame = load_scene(nrhints).split("test")[1]
    with pytest.raises(DatasetError, match="8×6 but the camera says 16×12"):
        frame.load()
    issues = validate_folder(nrhints).errors
    assert [issue.frame for issue in issues] == ["001"]


def test_nan_pixels_in_exr(tmp_path):
    write_gs3_tree(tmp_path / "g")
    pixels = np.full((12, 16, 4), 0.5, dtype=np.float32)
    pixels[3, 3, 0] = np.nan
    path = tmp_path / "g/test/r_1.exr"
    import OpenImageIO as oiio

    output = oiio.ImageOutput.create(str(path))
    output.open(str(path), oiio.ImageSpec(16, 12, 4, "float"))
    output.write_image(pixels)
    output.close()
    with pytest.raises(DatasetError, match="NaN or Inf pixels"):
        load_scene(tmp_path / "g").split("test")[1].load()


def test_sssgs_list_length_mismatch(tmp_path):
    write_sssgs_tree(tmp_path / "s")
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][1]["light_positions"].pop())
    with pytest.raises(DatasetError, match="list lengths differ") as error:
        load_scene(tmp_path / "s")
    assert error.value.frame == 1


def test_sssgs_missing_width(tmp_path):
    write_sssgs_tree(tmp_path / "s")
    _edit(tmp_path / "s/transforms_test.json", lambda m: m["frames"][0].pop("width"))
    with pytest.raises(DatasetError, match="key 'width'"):
        load_scene(tmp_path / "s")


def test_validate_collects_every_bad_frame(nrhints):
    _edit(
        nrhints / "transforms_train.json", lambda m: [m["frames"][i].pop("pl_pos") for i in (1, 3)]
    )
    (nrhints / "test/000.png").write_bytes(b"broken")
    report = validate_folder(nrhints)
    frames = sorted(issue.frame for issue in report.errors)
    assert frames == ["000", "001", "003"]
    assert report.frames == {"train": 2, "test": 2}


def test_validate_light_inside_camera_and_bad_rotation(tmp_path):
    tree = write_gs3_tree(tmp_path / "g")
    eye = tree.frames["train"][1]["c2w_gl"][:3, 3]

    def change(meta):
        meta["frames"][1]["pl_pos"] = (eye + np.array([0.1, 0.0, 0.0])).tolist()  # 0.1 < near = 0.5
        matrix = np.array(meta["frames"][2]["transform_matrix"])
        matrix[:3, 0] *= 2.0
        meta["frames"][2]["transform_matrix"] = matrix.tolist()

    _edit(tmp_path / "g/transforms_train.json", change)
    report = validate_folder(tmp_path / "g")
    messages = {(issue.frame, issue.key): issue.message for issue in report.errors}
    assert "inside the camera" in messages[("r_1", "pl_pos")]
    assert "orthonormal" in messages[("r_2", "transform_matrix")]


def test_sssgs_off_centre_principal_point_is_a_warning(tmp_path):
    write_sssgs_tree(tmp_path / "s")
    _edit(tmp_path / "s/transforms_train.json", lambda m: m["frames"][1].update(cx=3.0))
    report = validate_folder(tmp_path / "s")
    assert report.ok and [issue.key for issue in report.issues] == ["cx"]
    assert "3 records" in report.issues[0].message


def test_clean_trees_validate(tmp_path):
    write_nrhints_tree(tmp_path / "a", n_path=2)
    write_gs3_tree(tmp_path / "b")
    write_sssgs_tree(tmp_path / "c", share_first=True, excluded=("r_0_l_1",))
    for name in "abc":
        report = validate_folder(tmp_path / name)
        assert report.ok and not report.issues, report.issues


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores file permissions")
def test_read_only_tree_is_read_and_validated(nrhints):
    for path in [nrhints, *nrhints.rglob("*")]:
        path.chmod(0o555 if path.is_dir() else 0o444)
    try:
        assert validate_folder(nrhints).ok
    finally:
        for path in [nrhints, *nrhints.rglob("*")]:
            path.chmod(0o755 if path.is_dir() else 0o644)


def test_reading_never_writes_into_the_tree(nrhints):
    before = {p: p.stat().st_mtime_ns for p in nrhints.rglob("*")}
    scene = load_scene(nrhints)
    for frame in scene:
        if frame.image_path is not None:
            frame.load()
    validate_folder(nrhints)
    assert {p: p.stat().st_mtime_ns for p in nrhints.rglob("*")} == before
