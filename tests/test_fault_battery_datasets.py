"""The fault battery for datasets and downloads (#38): every corruption below, written into a small
tree of each official format (`datasets_trees`), meets each entry point —
``olatbench datasets validate``, ``olatbench datasets info`` and ``load_scene``/``Frame.load`` — and
must end in one error naming the file (and the field where there is one), the documented exit code,
and no traceback. Damaged and malicious archives meet ``olatbench datasets download`` through a
``file://`` mirror: one error naming the archive, nothing written outside the data root's temporary
folder, no hash recorded, the archive set aside so that the rerun after the mirror is fixed installs
the scene. A ``file://`` copy cut off half-way leaves nothing under the cache's name. Damaged scene
manifests meet ``datasets verify`` and ``datasets download``; damaged Hub listings meet
``datasets download``: one error naming the file (or listing entry) and the field.

Counts (kept true by `test_the_counts_in_this_docstring_are_true`, quoted in docs/guarantees.md): 34
corruptions give 99 broken scenes over the three formats, met by 3 entry points: 297 dataset cases;
22 archives, 1 cut-off copy, 7 damaged manifests, 4 damaged Hub listings: 331 cases in all.

Exit codes checked: ``validate`` 1 on any error; ``info`` 1 when a scene cannot be read; both 0
otherwise (``info`` reads the transforms files and at most one image header, so a broken image
elsewhere is for ``validate`` and ``Frame.load`` to find); ``download`` 1 when a scene failed.
"""

from __future__ import annotations

import bz2
import gzip
import io
import json
import lzma
import math
import os
import re
import shutil
import tarfile
import zipfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from datasets_trees import write_gs3_tree, write_nrhints_tree, write_sssgs_tree

from olatbench.cli import main
from olatbench.datasets import DatasetError, load_scene
from olatbench.datasets.download import archives, fetch, manifest
from olatbench.datasets.errors import printable
from olatbench.datasets.images import write_image

FORMATS = ("nrhints", "gs3", "sssgs")
ENTRY_POINTS = ("validate", "info", "load")


@dataclass(frozen=True)
class Layout:
    """Where things are in the small tree of one format: the test split's file, the frame broken by
    the cases (``frame``: index in its ``frames`` list), that frame's image and the JSON keys naming
    it and its light."""

    split_file: str
    frame: int
    image: str  # relative to the scene folder
    image_key: str  # the key a bad image path is reported under
    light_key: str
    intrinsics: tuple[str, object]  # (key, a bad value)
    # the image whose header gives the scene's size (read by load_scene), if any
    size_image: str | None


LAYOUTS = {
    "nrhints": Layout(
        "transforms_test.json",
        1,
        "test/001.png",
        "file_path",
        "pl_pos",
        ("camera_intrinsics", [1.0, 2.0, 3.0]),
        "train/000.png",
    ),
    "gs3": Layout(
        "transforms_test.json",
        1,
        "test/r_1.exr",
        "file_path",
        "pl_pos",
        ("camera_angle_x", -1.0),
        "train/r_0.exr",
    ),
    "sssgs": Layout(
        "transforms_test.json",
        0,
        "test/r_0_l_1.png",
        "file_paths[1]",
        "light_positions[1]",
        ("fl_x", "wide"),
        None,
    ),
}


@dataclass(frozen=True)
class Expected:
    """What the one error must say: the file (relative to the scene folder), the key (or None) and a
    phrase of the message; ``scene`` is True when reading the scene fails
    (``load_scene``, ``info``), False when only the frame's image does (``Frame.load``)."""

    file: str
    key: str | None
    phrase: str
    scene: bool = True


def _edit(root: Path, layout: Layout, change: Callable[[dict], None]) -> None:
    path = root / layout.split_file
    meta = json.loads(path.read_text())
    change(meta)
    path.write_text(json.dumps(meta))


def _frame_edit(root: Path, layout: Layout, change: Callable[[dict], None]) -> None:
    _edit(root, layout, lambda meta: change(meta["frames"][layout.frame]))


def _set_light(frame: dict, fmt: str, value) -> None:
    if fmt == "sssgs":
        frame["light_positions"][1] = value
    else:
        frame["pl_pos"] = value


def _replace_image(root: Path, layout: Layout, pixels: np.ndarray) -> None:
    (root / layout.image).unlink()
    write_image(root / layout.image, pixels, "half" if layout.image.endswith(".exr") else "uint8")


def _nan_exr(path: Path) -> None:
    import OpenImageIO as oiio

    pixels = np.full((12, 16, 4), 0.5, dtype=np.float32)
    pixels[3, 3, 0] = np.nan
    path.unlink()
    output = oiio.ImageOutput.create(str(path))
    output.open(str(path), oiio.ImageSpec(16, 12, 4, "float"))
    output.write_image(pixels)
    output.close()


def _non_utf8_name(root: Path, layout: Layout, fmt: str) -> str:
    """Rename the frame's image to a name holding the byte 0xff and point the JSON at it; the new
    name."""
    image = root / layout.image
    renamed = Path(
        os.fsdecode(os.fsencode(image.with_suffix("")) + b"\xff" + os.fsencode(image.suffix))
    )
    image.rename(renamed)
    stem = str(Path(layout.image).with_suffix("")) + os.fsdecode(b"\xff")

    def change(frame):
        if fmt == "sssgs":
            frame["file_paths"][1] = stem
        else:
            frame["file_path"] = stem

    _frame_edit(root, layout, change)
    return str(renamed.relative_to(root))


# --- the corruptions: each writes one fault into a fresh tree and says what the error must name


def _image_cases() -> dict[str, Callable[[Path, Layout, str], Expected | None]]:
    def truncated(root, layout, fmt):
        data = (root / layout.image).read_bytes()
        (root / layout.image).write_bytes(data[: len(data) // 2])
        return Expected(layout.image, None, "", scene=False)

    def zero_byte(root, layout, fmt):
        (root / layout.image).write_bytes(b"")
        return Expected(layout.image, None, "cannot open image", scene=False)

    def not_an_image(root, layout, fmt):
        (root / layout.image).write_bytes(b"\x89PNG not really" + bytes(200))
        return Expected(layout.image, None, "", scene=False)

    def wrong_depth(root, layout, fmt):
        _replace_image(
            root, layout, np.full((16 if fmt == "sssgs" else 12, 16, 2), 0.5, dtype=np.float32)
        )
        return Expected(layout.image, None, "expected 1, 3 or 4 channels, found 2", scene=False)

    def wrong_size(root, layout, fmt):
        _replace_image(root, layout, np.full((6, 8, 4), 0.5, dtype=np.float32))
        return Expected(layout.image, None, "but the camera says", scene=False)

    def nan_pixels(root, layout, fmt):
        if fmt != "gs3":
            return None  # 8-bit PNGs cannot hold NaN
        _nan_exr(root / layout.image)
        return Expected(layout.image, None, "NaN or Inf pixels", scene=False)

    def missing(root, layout, fmt):
        (root / layout.image).unlink()
        return Expected(layout.image, None, "not found", scene=False)

    def link_loop(root, layout, fmt):
        (root / layout.image).unlink()
        os.symlink(Path(layout.image).name, root / layout.image)
        return Expected(layout.image, None, "symbolic link loop", scene=False)

    def folder_instead(root, layout, fmt):
        (root / layout.image).unlink()
        (root / layout.image).mkdir()
        return Expected(layout.image, None, "is a folder", scene=False)

    def non_utf8_name(root, layout, fmt):
        return Expected(_non_utf8_name(root, layout, fmt), None, "not valid UTF-8", scene=False)

    def size_image_empty(root, layout, fmt):
        if layout.size_image is None:
            return None  # SSS-GS frames carry width/height: no image is read for the size
        (root / layout.size_image).write_bytes(b"")
        return Expected(layout.size_image, None, "needed for the image size")

    return {
        f.__name__: f
        for f in (
            truncated,
            zero_byte,
            not_an_image,
            wrong_depth,
            wrong_size,
            nan_pixels,
            missing,
            link_loop,
            folder_instead,
            non_utf8_name,
            size_image_empty,
        )
    }


def _json_cases() -> dict[str, Callable[[Path, Layout, str], Expected | None]]:
    def json_truncated(root, layout, fmt):
        path = root / layout.split_file
        path.write_text(path.read_text()[: len(path.read_text()) // 2])
        return Expected(layout.split_file, None, "malformed JSON")

    def json_zero_byte(root, layout, fmt):
        (root / layout.split_file).write_bytes(b"")
        return Expected(layout.split_file, None, "malformed JSON")

    def json_not_utf8(root, layout, fmt):
        (root / layout.split_file).write_bytes(b'{"frames": ["\xff\xfe"]}')
        return Expected(layout.split_file, None, "cannot read")

    def json_not_an_object(root, layout, fmt):
        (root / layout.split_file).write_text("[]")
        return Expected(layout.split_file, None, "JSON object")

    def json_folder_instead(root, layout, fmt):
        (root / layout.split_file).unlink()
        (root / layout.split_file).mkdir()
        return Expected(layout.split_file, None, "is a folder")

    def json_link_loop(root, layout, fmt):
        (root / layout.split_file).unlink()
        os.symlink(layout.split_file, root / layout.split_file)
        return Expected(layout.split_file, None, "symbolic link loop")

    def json_dangling_link(root, layout, fmt):
        (root / layout.split_file).unlink()
        os.symlink("moved_away.json", root / layout.split_file)
        return Expected(layout.split_file, None, "link to a missing file")

    def frames_not_a_list(root, layout, fmt):
        _edit(root, layout, lambda meta: meta.update(frames={"0": {}}))
        return Expected(layout.split_file, "frames", "expected a list")

    def frame_not_an_object(root, layout, fmt):
        _edit(root, layout, lambda meta: meta["frames"].__setitem__(layout.frame, [1, 2, 3]))
        return Expected(layout.split_file, "frames", "expected a JSON object")

    def frames_missing(root, layout, fmt):
        _edit(root, layout, lambda meta: meta.pop("frames"))
        return Expected(layout.split_file, "frames", "missing key")

    def frames_empty(root, layout, fmt):
        _edit(root, layout, lambda meta: meta.update(frames=[]))
        return Expected(layout.split_file, "frames", "empty list")

    def matrix_missing(root, layout, fmt):
        _frame_edit(root, layout, lambda frame: frame.pop("transform_matrix"))
        return Expected(layout.split_file, "transform_matrix", "missing key")

    def matrix_nan(root, layout, fmt):
        _frame_edit(root, layout, lambda frame: frame.update(transform_matrix=[[math.nan] * 4] * 4))
        return Expected(layout.split_file, "transform_matrix", "NaN or Inf")

    def matrix_wrong_shape(root, layout, fmt):
        _frame_edit(root, layout, lambda frame: frame.update(transform_matrix=np.eye(3).tolist()))
        return Expected(layout.split_file, "transform_matrix", "expected shape (4, 4)")

    def light_inf(root, layout, fmt):
        _frame_edit(root, layout, lambda frame: _set_light(frame, fmt, [0.0, math.inf, 1.0]))
        return Expected(layout.split_file, layout.light_key, "NaN or Inf")

    def light_wrong_shape(root, layout, fmt):
        _frame_edit(root, layout, lambda frame: _set_light(frame, fmt, [1.0, 2.0]))
        return Expected(layout.split_file, layout.light_key, "expected shape (3,)")

    def bad_intrinsics(root, layout, fmt):
        key, value = layout.intrinsics
        # the NeRF-style trees keep intrinsics at the top level
        target = _frame_edit if fmt == "sssgs" else _edit
        target(root, layout, lambda entry: entry.update({key: value}))
        return Expected(layout.split_file, key, "")

    def path_escapes(root, layout, fmt):
        def change(frame):
            if fmt == "sssgs":
                frame["file_paths"][1] = "../../../etc/passwd"
            else:
                frame["file_path"] = "../../../etc/passwd"

        _frame_edit(root, layout, change)
        return Expected(layout.split_file, layout.image_key, "leaves the dataset root")

    def path_not_a_string(root, layout, fmt):
        def change(frame):
            if fmt == "sssgs":
                frame["file_paths"][1] = 7
            else:
                frame["file_path"] = 7

        _frame_edit(root, layout, change)
        return Expected(layout.split_file, layout.image_key, "expected a non-empty relative path")

    def json_nested_too_deep(root, layout, fmt):
        (root / layout.split_file).write_text('{"frames": ' + "[" * 100_000 + "]" * 100_000 + "}")
        return Expected(layout.split_file, None, "nested too deeply")

    def json_integer_too_long(root, layout, fmt):
        path = root / layout.split_file
        path.write_text(
            path.read_text().replace('"frames"', '"scale": ' + "7" * 5000 + ', "frames"', 1)
        )
        return Expected(layout.split_file, None, "an integer with more digits")

    def matrix_reflection(root, layout, fmt):
        def mirror(frame):
            frame["transform_matrix"] = [
                [-row[0], *row[1:]] for row in frame["transform_matrix"][:3]
            ] + frame["transform_matrix"][3:]

        _frame_edit(root, layout, mirror)
        return Expected(layout.split_file, "transform_matrix", "reflection")

    def light_huge(root, layout, fmt):
        _frame_edit(root, layout, lambda frame: _set_light(frame, fmt, [1e308, 0.0, 1.0]))
        return Expected(layout.split_file, layout.light_key, "magnitude above")

    return {
        f.__name__: f
        for f in (
            json_truncated,
            json_zero_byte,
            json_not_utf8,
            json_not_an_object,
            json_folder_instead,
            json_link_loop,
            json_dangling_link,
            json_nested_too_deep,
            json_integer_too_long,
            frames_missing,
            frames_not_a_list,
            frame_not_an_object,
            frames_empty,
            matrix_missing,
            matrix_nan,
            matrix_wrong_shape,
            matrix_reflection,
            light_inf,
            light_huge,
            light_wrong_shape,
            bad_intrinsics,
            path_escapes,
            path_not_a_string,
        )
    }


CORRUPTIONS = {**_image_cases(), **_json_cases()}
WRITERS = {
    "nrhints": lambda root: write_nrhints_tree(root, n_train=3, n_test=2),
    "gs3": lambda root: write_gs3_tree(root, n_train=3, n_test=2),
    "sssgs": lambda root: write_sssgs_tree(
        root, n_train_cameras=2, n_test_cameras=1, lights_per_camera=2
    ),
}


@pytest.fixture(scope="module")
def clean_trees(tmp_path_factory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("clean")
    return {fmt: WRITERS[fmt](base / fmt).root for fmt in FORMATS}


def _applicable() -> list[tuple[str, str]]:
    """(corruption, format) pairs that exist (a NaN pixel needs an EXR; a size image needs a
    NeRF-style tree)."""
    pairs = []
    for name in CORRUPTIONS:
        for fmt in FORMATS:
            if name == "nan_pixels" and fmt != "gs3":
                continue
            if name == "size_image_empty" and LAYOUTS[fmt].size_image is None:
                continue
            pairs.append((name, fmt))
    return pairs


BROKEN_SCENES = _applicable()


def _broken(clean_trees, tmp_path: Path, name: str, fmt: str) -> tuple[Path, Expected]:
    root = tmp_path / {"nrhints": "Pixiu", "gs3": "Lego", "sssgs": "bunny_small"}[fmt]
    shutil.copytree(clean_trees[fmt], root, symlinks=True)
    expected = CORRUPTIONS[name](root, LAYOUTS[fmt], fmt)
    assert expected is not None
    return root, expected


def _no_traceback(result) -> None:
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        f"{type(result.exception).__name__}: {result.exception}"
    )
    assert "Traceback" not in result.output


@pytest.mark.filterwarnings("error::RuntimeWarning")  # an overflow in numpy is no error message
@pytest.mark.parametrize("entry", ENTRY_POINTS)
@pytest.mark.parametrize(("name", "fmt"), BROKEN_SCENES, ids=[f"{n}-{f}" for n, f in BROKEN_SCENES])
def test_broken_scene(clean_trees, tmp_path, name, fmt, entry):
    root, expected = _broken(clean_trees, tmp_path, name, fmt)
    file = root / expected.file
    if entry == "validate":
        result = CliRunner().invoke(main, ["datasets", "validate", str(root), "--json"])
        _no_traceback(result)
        assert result.exit_code == 1, result.output
        (report,) = json.loads(result.stdout)
        errors = [issue for issue in report["issues"] if issue["severity"] == "error"]
        assert len(errors) == 1, errors
        (issue,) = errors
        assert issue["path"] == str(file) and issue["key"] == expected.key, issue
        assert expected.phrase in issue["message"], issue
        text = CliRunner().invoke(main, ["datasets", "validate", str(root), "--quiet"])
        _no_traceback(text)
        assert text.exit_code == 1 and printable(file) in text.output
    elif entry == "info":
        result = CliRunner().invoke(main, ["datasets", "info", str(root)])
        _no_traceback(result)
        if expected.scene:
            assert result.exit_code == 1, result.output
            assert printable(file) in result.output and expected.phrase in result.output
            assert expected.key is None or f"key '{expected.key}'" in result.output
            assert len(re.findall(r"^Error:", result.output, flags=re.M)) == 1
        else:
            assert result.exit_code == 0, result.output  # info reads no pixels of this frame
    else:
        if expected.scene:
            with pytest.raises(DatasetError) as error:
                load_scene(root)
        else:
            scene = load_scene(root)
            (frame,) = [f for f in scene.split("test") if f.image_path == file]
            with pytest.raises(DatasetError) as error:
                frame.load()
        assert error.value.path == file and error.value.key == expected.key, str(error.value)
        assert expected.phrase in error.value.message


# --- archives -------------------------------------------------------------------------------------


def _tar(members: list[tarfile.TarInfo | tuple[str, bytes]], mode: str = "w") -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode=mode) as bundle:
        for member in members:
            if isinstance(member, tarfile.TarInfo):
                bundle.addfile(member)
            else:
                info = tarfile.TarInfo(member[0])
                info.size = len(member[1])
                bundle.addfile(info, io.BytesIO(member[1]))
    return buffer.getvalue()


def _zip(members: list[tuple[str, bytes]], compression: int = zipfile.ZIP_STORED) -> bytes:
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=compression) as bundle:
        for name, data in members:
            bundle.writestr(name, data)
    return buffer.getvalue()


def _special(name: str, kind: bytes, link: str = "") -> tarfile.TarInfo:
    info = tarfile.TarInfo(name)
    info.type, info.linkname = kind, link
    return info


def _corrupt_middle(data: bytes) -> bytes:
    damaged = bytearray(data)
    for index in range(len(damaged) // 2, len(damaged) // 2 + 64):
        damaged[index] ^= 0xA5
    return bytes(damaged)


def _archives(scene_tar: bytes, scene_zip_deflated: bytes) -> dict[str, tuple[bytes, str]]:
    """{case: (archive bytes, phrase of the expected error)}: damaged archives, bombs, escaping
    members."""
    zeros = bytes(80 << 20)  # 80 MiB of zeros: a few hundred kB compressed, over the 64 MiB floor
    symlink_zip = io.BytesIO()
    with zipfile.ZipFile(symlink_zip, "w") as bundle:
        info = zipfile.ZipInfo("scene/link")
        info.external_attr = 0o120777 << 16
        bundle.writestr(info, "/etc/passwd")
    return {
        "zip_truncated": (
            scene_zip_deflated[: len(scene_zip_deflated) // 2],
            "damaged or truncated archive",
        ),
        "zip_corrupt_deflate": (
            _corrupt_middle(scene_zip_deflated),
            "damaged or truncated archive",
        ),
        "tar_truncated": (scene_tar[: len(scene_tar) // 2 + 100], "damaged or truncated archive"),
        "tar_gz_truncated": (gzip.compress(scene_tar)[:-200], "damaged or truncated archive"),
        "tar_gz_corrupt": (
            _corrupt_middle(gzip.compress(scene_tar)),
            "damaged or truncated archive",
        ),
        "tar_bz2_truncated": (bz2.compress(scene_tar)[:-200], "damaged or truncated archive"),
        "tar_xz_truncated": (lzma.compress(scene_tar)[:-200], "damaged or truncated archive"),
        "zero_byte": (b"", "damaged or truncated archive"),
        "not_an_archive": (b"<html>404 Not Found</html>", "damaged or truncated archive"),
        "bomb_zip": (
            _zip([("scene/zeros.bin", zeros)], zipfile.ZIP_DEFLATED),
            "decompression bomb",
        ),
        "bomb_tar_gz": (
            gzip.compress(_tar([("scene/zeros.bin", zeros)]), compresslevel=1),
            "decompression bomb",
        ),
        "traversal_dotdot": (
            _zip([("scene/ok.txt", b"x"), ("../evil.txt", b"x")]),
            "escapes the destination",
        ),
        "traversal_absolute": (_tar([("/tmp/evil.txt", b"x")]), "escapes the destination"),
        "traversal_drive": (_zip([("C:/evil.txt", b"x")]), "escapes the destination"),
        "symlink_member": (
            _tar([_special("scene/link", tarfile.SYMTYPE, "/etc/passwd")]),
            "link or device",
        ),
        "symlink_member_zip": (symlink_zip.getvalue(), "link or device"),
        "hardlink_member": (
            _tar([_special("scene/link", tarfile.LNKTYPE, "/etc/passwd")]),
            "link or device",
        ),
        "dot_member": (_tar([(".", b"x")]), "without a file name"),
        "file_and_folder_of_one_name": (
            _tar([("CatSmall/a", b"x"), ("CatSmall/a/b", b"y")]),
            "folder of the same name",
        ),
        "file_and_folder_of_one_name_zip": (
            _zip([("CatSmall/a.png/b", b"y"), ("CatSmall/a.png", b"x")]),
            "folder of the same name",
        ),
        "member_name_too_long": (
            _zip([("CatSmall/" + "n" * 300 + ".png", b"x")]),
            "cannot be unpacked as a file",
        ),
        "member_path_too_long": (
            _tar([("CatSmall/" + "/".join(["d" * 200] * 25) + "/x.png", b"x")]),
            "cannot be unpacked as a file",
        ),
    }


@pytest.fixture(scope="module")
def archive_cases(clean_trees, tmp_path_factory) -> dict[str, tuple[bytes, str]]:
    folder = tmp_path_factory.mktemp("scene") / "CatSmall"
    shutil.copytree(clean_trees["nrhints"], folder)
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w") as bundle:
        bundle.add(folder, arcname="CatSmall")
    deflated = io.BytesIO()
    with zipfile.ZipFile(deflated, "w", zipfile.ZIP_DEFLATED) as bundle:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                bundle.write(path, f"CatSmall/{path.relative_to(folder)}")
    return _archives(buffer.getvalue(), deflated.getvalue())


@pytest.fixture(scope="module")
def good_archive(clean_trees) -> bytes:
    """A valid CatSmall scene as the zip the source serves: what a fixed mirror holds."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w") as bundle:
        for path in sorted(clean_trees["nrhints"].rglob("*")):
            if path.is_file():
                bundle.write(path, f"CatSmall/{path.relative_to(clean_trees['nrhints'])}")
    return buffer.getvalue()


ARCHIVE_CASES = (
    "zip_truncated",
    "zip_corrupt_deflate",
    "tar_truncated",
    "tar_gz_truncated",
    "tar_gz_corrupt",
    "tar_bz2_truncated",
    "tar_xz_truncated",
    "zero_byte",
    "not_an_archive",
    "bomb_zip",
    "bomb_tar_gz",
    "traversal_dotdot",
    "traversal_absolute",
    "traversal_drive",
    "symlink_member",
    "symlink_member_zip",
    "hardlink_member",
    "dot_member",
    "file_and_folder_of_one_name",
    "file_and_folder_of_one_name_zip",
    "member_name_too_long",
    "member_path_too_long",
)


def _download(root: Path, mirror: Path):
    return CliRunner().invoke(
        main,
        [
            "datasets",
            "download",
            "nrhints",
            "--scenes",
            "CatSmall",
            "--data-root",
            str(root),
            "--source",
            "nrhints-project",
            "--mirror",
            mirror.as_uri(),
            "--quiet",
        ],
    )


@pytest.mark.parametrize("case", ARCHIVE_CASES)
def test_broken_archive(archive_cases, good_archive, tmp_path, case):
    data, phrase = archive_cases[case]
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    (mirror / "CatSmall.zip").write_bytes(data)  # the source's file name, whatever the content
    root = tmp_path / "box" / "data"
    root.mkdir(parents=True)
    result = _download(root, mirror)
    _no_traceback(result)
    assert result.exit_code == 1, result.output
    assert re.search(rf"CatSmall\.zip: .*{re.escape(phrase)}", result.output), result.output
    # the archive is named, not the temporary folder it was unpacked in
    assert ".unpack-" not in result.output
    assert len(re.findall(r"FAILED", result.output)) == 1
    # nothing escaped the root
    assert sorted(p.name for p in (tmp_path / "box").iterdir()) == ["data"]
    # no scene, no recorded hash, no temp
    assert sorted(p.name for p in root.iterdir()) == [fetch.DOWNLOADS]
    cached = sorted(p.name for p in (root / fetch.DOWNLOADS / "nrhints-project").iterdir())
    assert cached == ["CatSmall.zip.damaged"]  # set aside: a rerun downloads it again
    # the mirror is fixed: the plain rerun installs the scene
    (mirror / "CatSmall.zip").write_bytes(good_archive)
    rerun = _download(root, mirror)
    assert rerun.exit_code == 0, rerun.output
    assert load_scene(root / "CatSmall").name == "CatSmall"


def test_a_local_copy_cut_off_mid_way_leaves_nothing_under_the_cache_name(
    good_archive, tmp_path, monkeypatch
):
    """A ``file://`` copy interrupted half-way (Ctrl-C, a killed process) leaves at most a ``.part``
    file: the next run copies it afresh and installs the scene at once (#48)."""
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    (mirror / "CatSmall.zip").write_bytes(good_archive)
    root = tmp_path / "data"
    real_copyfile = shutil.copyfile

    def cut_off(source, target, *args, **kwargs):
        Path(target).write_bytes(Path(source).read_bytes()[: len(good_archive) // 2])
        raise KeyboardInterrupt

    monkeypatch.setattr(shutil, "copyfile", cut_off)
    with pytest.raises(KeyboardInterrupt):
        fetch.download_scene(
            "nrhints",
            "CatSmall",
            root,
            source="nrhints-project",
            mirror=mirror.as_uri(),
            progress=False,
        )
    monkeypatch.setattr(shutil, "copyfile", real_copyfile)
    assert not (root / fetch.DOWNLOADS / "nrhints-project" / "CatSmall.zip").exists()
    rerun = _download(root, mirror)
    assert rerun.exit_code == 0, rerun.output
    assert load_scene(root / "CatSmall").name == "CatSmall"


# --- damaged scene manifests: `datasets verify` names the file and the field; `datasets download`
# replaces the scene

MANIFEST_DAMAGE = {
    "a list": (lambda path: path.write_text("[]"), "expected a JSON object"),
    "files not an object": (
        lambda path: path.write_text('{"source": "x", "files": ["a.png"]}'),
        "key 'files'",
    ),
    "files missing": (lambda path: path.write_text('{"source": "x"}'), "key 'files'"),
    "a hash that is no text": (
        lambda path: path.write_text('{"files": {"test/000.png": 5}}'),
        "key 'files.test/000.png'",
    ),
    "not UTF-8": (lambda path: path.write_bytes(b'{"files": {"\xff\xfe": "0"}}'), "not UTF-8"),
    "truncated": (
        lambda path: path.write_bytes(path.read_bytes()[: path.stat().st_size // 2]),
        "malformed JSON",
    ),
    "nested too deep": (
        lambda path: path.write_text("[" * 100_000 + "]" * 100_000),
        "nested too deeply",
    ),
}


@pytest.mark.parametrize("damage", list(MANIFEST_DAMAGE))
def test_a_damaged_scene_manifest(good_archive, tmp_path, damage):
    mirror = tmp_path / "mirror"
    mirror.mkdir()
    (mirror / "CatSmall.zip").write_bytes(good_archive)
    root = tmp_path / "data"
    assert _download(root, mirror).exit_code == 0
    write, phrase = MANIFEST_DAMAGE[damage]
    path = root / "CatSmall" / manifest.MANIFEST_NAME
    write(path)
    verify = CliRunner().invoke(main, ["datasets", "verify", str(root)])
    _no_traceback(verify)
    assert verify.exit_code == 1 and "CatSmall: DAMAGED" in verify.output, verify.output
    (line,) = [line for line in verify.output.splitlines() if line.startswith("Error:")]
    assert f"{printable(path)}: malformed manifest" in line and phrase in line, line
    # a scene whose manifest is damaged is set aside and downloaded again
    rerun = _download(root, mirror)
    _no_traceback(rerun)
    assert rerun.exit_code == 0, rerun.output
    assert manifest.verify_folder(root / "CatSmall") == []
    assert len(list(root.glob("CatSmall.replaced-*"))) == 1


# --- damaged Hub listings: one error naming the listing, the entry and the field ------------------

HUB_DAMAGE = {
    "size that is text": ({"size": "big"}, "key 'size'"),
    "negative size": ({"size": -1}, "key 'size'"),
    "lfs that is a list": ({"lfs": ["oid"]}, "key 'lfs'"),
    "lfs oid that is no sha256": ({"lfs": {"oid": 5, "size": 1}}, "key 'lfs.oid'"),
}


@pytest.mark.parametrize("damage", list(HUB_DAMAGE))
def test_a_damaged_hub_listing(good_archive, tmp_path, damage):
    from http_fixture import LocalServer, ServerState

    from olatbench.datasets.download.sources import GS3_REPO, GS3_REVISION

    state = ServerState()
    name = "NRHints/Cat_on_Decor.zip"
    state.files[f"/datasets/{GS3_REPO}/resolve/{GS3_REVISION}/{name}"] = good_archive
    change, phrase = HUB_DAMAGE[damage]
    state.listings[f"/api/datasets/{GS3_REPO}/tree/{GS3_REVISION}"] = [
        {"type": "file", "path": name, "size": len(good_archive), **change}
    ]
    root = tmp_path / "data"
    with LocalServer(state) as server:
        result = CliRunner().invoke(
            main,
            [
                "datasets",
                "download",
                "nrhints",
                "--scenes",
                "CatSmall",
                "--data-root",
                str(root),
                "--source",
                "gs3-hf",
                "--mirror",
                server.url,
                "--quiet",
            ],
        )
    _no_traceback(result)
    assert result.exit_code == 1, result.output
    assert re.search(
        rf"tree/{GS3_REVISION}\?recursive=true: entry 0 \('{name}'\): {re.escape(phrase)}",
        result.output,
    ), result.output
    assert not (root / "CatSmall").exists()


def test_the_counts_in_this_docstring_are_true(archive_cases):
    assert tuple(archive_cases) == ARCHIVE_CASES
    scenes, dataset_cases = len(BROKEN_SCENES), len(BROKEN_SCENES) * len(ENTRY_POINTS)
    stated = re.search(
        r"(\d+) corruptions give (\d+) broken scenes over the three formats, met by (\d+) entry "
        r"points: (\d+) dataset cases;\s+(\d+) archives, 1 cut-off copy, (\d+) damaged manifests, "
        r"(\d+) damaged Hub listings: (\d+) cases in all",
        " ".join(__doc__.split()),
    )
    assert stated is not None
    others = len(ARCHIVE_CASES) + 1 + len(MANIFEST_DAMAGE) + len(HUB_DAMAGE)
    assert tuple(map(int, stated.groups())) == (
        len(CORRUPTIONS),
        scenes,
        len(ENTRY_POINTS),
        dataset_cases,
        len(ARCHIVE_CASES),
        len(MANIFEST_DAMAGE),
        len(HUB_DAMAGE),
        dataset_cases + others,
    )
    # the bombs above exceed the limit whatever the archive's size
    assert archives.UNPACK_FLOOR < 80 << 20
