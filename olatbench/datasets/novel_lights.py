"""Ground truth under new illumination: a scene's test cameras rendered under lightings that are not
one point light.

For the mini suite (`olatbench.datasets.synth.mini`) the package carries a fixed set of conditions,
`CONDITIONS`, each a lighting file (``olatbench/datasets/synth/data/novel_lights/<condition>.json``,
the format of docs/relighting.md), and each mini scene's test views rendered under each of them once
with Mitsuba 3 (`olatbench.datasets.synth.lit.render_lit`, environment maps whole) on the reference
machine: the archives ``data/novel_lights/<scene>.tar.xz`` and every file's sha256 in
``data/novel_lights_reference.json`` (`olatbench.datasets.synth.reference.NOVEL_LIGHTS`).
`ensure_novel_lights` unpacks a scene's archive on first use and checks every byte, as the mini
suite's scenes are installed, so every machine scores against the same bytes and installing never
runs Mitsuba.

Layout, below a scene folder (an interface: the novel-illumination protocol reads it)::

    <scene>/novel_lights/manifest.json               the installed files' sha256 (mini scenes)
    <scene>/novel_lights/<condition>/lighting.json   the lighting (`lighting.read_lighting`)
    <scene>/novel_lights/<condition>/lit.json        render_lit's record: lighting, recipe, cameras,
                                                     versions
    <scene>/novel_lights/<condition>/<frame_id>.exr  linear RGB + straight alpha, one per test
                                                     frame, named as the scene's test split names
                                                     its frames (half floats for the packaged ones)

Any scene rendered by the generator gets the same layout with ``olatbench datasets synth --recipe R
--lights FILE.json -o <scene>/novel_lights/<condition>`` (``render_lit`` writes the three kinds of
file); such a folder is checked (every test frame, the lighting file, lit.json's frames) but carries
no hashes.

Torch-free, like the rest of the data layer.
"""

from __future__ import annotations

import json
import logging
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.lighting import Lighting, lighting_to_dict, read_lighting
from olatbench.datasets.synth.reference import (
    NOVEL_LIGHTS,
    SceneComparison,
    compare_scene,
    load_reference,
)
from olatbench.datasets.synth.reference import reference_root as package_root

#: The packaged conditions, in order: two and three coloured point lights, a rectangular area light
#: (16 points), and the built-in ``studio`` and ``sky`` maps (docs/relighting.md).
CONDITIONS: tuple[str, ...] = ("two_lights", "three_lights", "area", "studio", "sky")
FOLDER = NOVEL_LIGHTS.subfolder  # "novel_lights", inside a scene folder
LIGHTING_FILE = "lighting.json"
RECORD_FILE = "lit.json"
#: Samples per pixel of the packaged renders (4× the mini recipes' 64, 2× translucent's 128): their
#: Monte Carlo noise then stays far below any model's error (docs/relighting.md, the noise floor).
SPP = 256
#: The packaged EXRs' colours are half floats rounded to this many of their 10 mantissa bits
#: (relative error ≤ 2⁻⁷, 64 dB below the images, 25 dB under the Monte Carlo noise): a third
#: smaller archives (docs/relighting.md).
MANTISSA_BITS = 6
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class NovelCondition:
    """One condition of a scene: its ``name``, its ``lighting`` and the ground truth, ``frames``:
    frame id -> EXR path (linear RGB + straight alpha, (H, W, 4) when read with
    `olatbench.datasets.images.read_image`), in the order of the scene's test split."""

    name: str
    lighting: Lighting
    frames: dict[str, Path]


def lighting_file(condition: str) -> Path:
    """The packaged lighting file of one of `CONDITIONS`."""
    if condition not in CONDITIONS:
        raise KeyError(
            f"no packaged novel-light condition {condition!r}; conditions: {', '.join(CONDITIONS)}"
        )
    return package_root() / NOVEL_LIGHTS.folder / f"{condition}.json"


def condition_lighting(condition: str) -> Lighting:
    """The lighting of one of `CONDITIONS` (read from its packaged file)."""
    return read_lighting(lighting_file(condition))


def _json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise DatasetError(
            f"cannot read ({error.__class__.__name__}: {error})", path=path
        ) from None


def mini_scene_name(scene_folder: Path) -> str | None:
    """The mini scene a folder holds (its name is one of the mini scenes' and its ``synth.json``
    records that scene's recipe and this generator), or None (a scene of one's own: its novel lights
    are rendered by hand)."""
    from olatbench.datasets.synth.generate import GENERATOR_VERSION
    from olatbench.datasets.synth.mini import MINI_SCENES, mini_recipes

    name = Path(scene_folder).name
    if name not in MINI_SCENES or not (Path(scene_folder) / "synth.json").is_file():
        return None
    made_by = _json(Path(scene_folder) / "synth.json")
    recipe = json.loads(json.dumps(mini_recipes()[name].to_dict()))
    if (
        not isinstance(made_by, dict)
        or made_by.get("recipe") != recipe
        or made_by.get("generator_version") != GENERATOR_VERSION
    ):
        return None
    return name


def scene_test_frames(scene_folder: Path) -> list[str]:
    """The frame ids of a scene's test split, in order (a `DatasetError` when it has none)."""
    from olatbench.datasets import load_scene

    scene = load_scene(Path(scene_folder))
    ids = [frame.frame_id for frame in scene.split("test")]
    if not ids:
        raise DatasetError(
            "the scene has no test frames to hold ground truth under new illumination",
            path=scene_folder,
        )
    return ids


def check_condition(folder: Path, frame_ids: list[str]) -> Lighting:
    """Check one condition folder against a scene's test frame ids (its lighting file reads,
    ``lit.json`` names exactly these frames, each has its EXR); return its lighting. A
    `DatasetError` naming the file and field."""
    folder = Path(folder)
    if not folder.is_dir():
        raise DatasetError("no such condition folder", path=folder)
    lighting = read_lighting(folder / LIGHTING_FILE)
    record = _json(folder / RECORD_FILE)
    frames = record.get("frames") if isinstance(record, dict) else None
    if not isinstance(frames, dict):
        raise DatasetError("expected an object of frames", path=folder / RECORD_FILE, key="frames")
    if sorted(frames) != sorted(frame_ids):
        missing, extra = sorted(set(frame_ids) - set(frames)), sorted(set(frames) - set(frame_ids))
        raise DatasetError(
            f"the frames are not the scene's test frames (missing {missing[:3]}, not in the scene "
            f"{extra[:3]}); render them again for this scene",
            path=folder / RECORD_FILE,
            key="frames",
        )
    absent = [frame_id for frame_id in frame_ids if not (folder / f"{frame_id}.exr").is_file()]
    if absent:
        raise DatasetError(
            f"{len(absent)} test frame(s) have no image, e.g. {absent[0]}.exr", path=folder
        )
    return lighting


def _manifest_header() -> dict[str, Any]:
    from olatbench.datasets.synth.generate import GENERATOR_VERSION

    return {"generator_version": GENERATOR_VERSION, "conditions": list(CONDITIONS)}


def installed_files(folder: Path) -> tuple[dict[str, str] | None, str]:
    """(the files of a scene's ``novel_lights`` folder per its manifest, or None; why not) — None
    unless the manifest is this generator's and conditions' and every file's hash matches it."""
    from olatbench.datasets.synth.mini import MANIFEST, file_hashes

    manifest_path = Path(folder) / MANIFEST
    if not manifest_path.is_file():
        return None, "no manifest"
    try:
        manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:
        return None, f"unreadable manifest ({error})"
    if not isinstance(manifest, dict) or any(
        manifest.get(k) != v for k, v in _manifest_header().items()
    ):
        return None, "made by another generator version or set of conditions"
    files = file_hashes(Path(folder))
    if manifest.get("files") != files:
        wrong = sorted(set(files) ^ set(manifest.get("files") or {})) or sorted(
            p for p in files if files[p] != manifest["files"][p]
        )
        return None, f"files differ from the manifest (missing, extra or modified: e.g. {wrong[0]})"
    return files, "ok"


def _record_mismatch(folder: Path, scene: str, condition: str) -> str | None:
    """The first of ``generator_version``, ``lighting`` and ``recipe`` in a condition folder's
    ``lit.json`` that is not what `render_condition` records for this mini scene and condition
    today, or None."""
    from olatbench.datasets.synth.generate import GENERATOR_VERSION
    from olatbench.datasets.synth.mini import mini_recipes

    record = _json(folder / RECORD_FILE)
    expected = {
        "generator_version": GENERATOR_VERSION,
        "lighting": json.loads(json.dumps(lighting_to_dict(condition_lighting(condition)))),
        "recipe": json.loads(json.dumps(mini_recipes()[scene].with_overrides(spp=SPP).to_dict())),
    }
    return next(
        (
            key
            for key, value in expected.items()
            if not isinstance(record, dict) or record.get(key) != value
        ),
        None,
    )


def _check_packaged_records(partial: Path, scene: str) -> None:
    """Each unpacked condition's ``lit.json`` was made by this generator, of this scene's recipe,
    under the condition's packaged lighting: else the package and the code disagree (a
    `DatasetError` naming the file)."""
    for condition in CONDITIONS:
        key = _record_mismatch(partial / condition, scene, condition)
        if key is not None:
            raise DatasetError(
                f"the packaged renders were made with another {key} than this olatbench's; render "
                "them with: olatbench datasets synth --mini --render",
                path=partial / condition / RECORD_FILE,
                key=key,
            )


def _install(scene_folder: Path, scene: str, reference: dict[str, Any]) -> Path:
    """Unpack scene's packaged novel-light renders into ``<scene_folder>/.novel_lights.partial``,
    check every byte and record, write the manifest and rename it into place."""
    from olatbench.atomic import write_json
    from olatbench.datasets.synth.mini import MANIFEST, publish, unpack_verified

    partial = scene_folder / f".{FOLDER}.partial"
    files = unpack_verified(scene, partial, reference, NOVEL_LIGHTS)
    try:
        _check_packaged_records(partial, scene)
    except DatasetError:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    write_json(partial / MANIFEST, {**_manifest_header(), "files": files})
    return publish(scene_folder, FOLDER, partial)


def render_condition(scene: str, condition: str, out_dir: Path, progress: bool = True) -> Path:
    """Render mini scene ``scene``'s test views under one of `CONDITIONS` with Mitsuba as the
    package's were (the mini suite's pinned variant, `SPP` samples per pixel, half-float EXRs with
    `MANTISSA_BITS`) into the new folder ``out_dir``."""
    from olatbench.datasets.synth.backend import pinned_variant
    from olatbench.datasets.synth.lit import render_lit
    from olatbench.datasets.synth.mini import MINI_VARIANT, mini_recipes

    with pinned_variant(MINI_VARIANT):
        return render_lit(
            mini_recipes()[scene].with_overrides(spp=SPP),
            condition_lighting(condition),
            out_dir,
            progress=progress,
            bit_depth="half",
            mantissa_bits=MANTISSA_BITS,
        )


def render_novel_lights(scene_folder: Path, scene: str, progress: bool = True) -> Path:
    """Render mini scene ``scene``'s test views under every condition (`render_condition`) into
    ``<scene_folder>/novel_lights``, with its manifest (written into ``.novel_lights.partial`` and
    renamed into place). An interrupted render resumes: a condition whose ``lit.json``
    (written last) records what would be rendered now is kept."""
    from olatbench.atomic import write_json
    from olatbench.datasets.synth.mini import MANIFEST, file_hashes, publish

    partial = scene_folder / f".{FOLDER}.partial"
    for condition in CONDITIONS:
        done = (partial / condition / RECORD_FILE).is_file() and _record_mismatch(
            partial / condition, scene, condition
        ) is None
        if not done:
            shutil.rmtree(partial / condition, ignore_errors=True)
            render_condition(scene, condition, partial / condition, progress=progress)
    write_json(partial / MANIFEST, {**_manifest_header(), "files": file_hashes(partial)})
    return publish(scene_folder, FOLDER, partial)


def ensure_novel_lights(scene_folder: Path, render: bool = False, progress: bool = True) -> Path:
    """Make sure a scene's ground truth under new illumination is there and intact; return its
    ``novel_lights`` folder (module docstring).

    A mini scene (`mini_scene_name`) gets the packaged renders, unpacked and hash-checked, where
    they are missing, damaged (replaced, with a warning) or, in a scene that is itself the packaged
    reference, not the reference's bytes; a valid folder rendered on this machine is kept in a scene
    rendered on this machine. ``render``: render them with Mitsuba instead where missing or damaged
    (``olatbench datasets synth --mini --render``). Any other scene's folder is checked: each
    condition's lighting file and every test frame (`check_condition`). A `DatasetError` naming the
    file (and field) otherwise.
    """
    from olatbench.datasets.synth.mini import data_matches_reference, locked

    scene_folder = Path(scene_folder)
    folder = scene_folder / FOLDER
    scene = mini_scene_name(scene_folder)
    if scene is None:
        if not folder.is_dir():
            raise DatasetError(
                "no ground truth under new illumination here: render a condition with olatbench "
                "datasets synth --recipe R --lights FILE.json -o SCENE/novel_lights/NAME",
                path=folder,
            )
        frame_ids = scene_test_frames(scene_folder)
        for condition in condition_names(scene_folder):
            check_condition(folder / condition, frame_ids)
        return folder
    with locked(scene_folder.parent):
        files, reason = installed_files(folder)
        reference = None if render else load_reference(package=NOVEL_LIGHTS)
        if files is not None and (
            reference is None
            or files == reference["scenes"][scene]["files"]
            or data_matches_reference(scene_folder) is False
        ):
            return folder
        if folder.exists():
            log.warning(
                "%s: replacing the ground truth under new illumination with the %s (%s)",
                folder,
                "renders of this machine" if render else "packaged reference",
                reason if files is None else "this machine's renders, not the reference's bytes",
            )
        if reference is None:
            return render_novel_lights(scene_folder, scene, progress=progress)
        _install(scene_folder, scene, reference)
        log.info("%s: installed the packaged ground truth under new illumination", folder)
    return folder


def compare_novel_lights(scene_folder: Path) -> SceneComparison:
    """A mini scene's installed or rendered ``novel_lights`` against the packaged reference: which
    files differ, and by how much their pixels do."""
    from olatbench.datasets.synth.mini import manifest_files

    scene_folder = Path(scene_folder)
    files = manifest_files(scene_folder / FOLDER)
    if files is None:
        raise FileNotFoundError(
            f"{scene_folder / FOLDER}: no readable manifest; install or render it first"
        )
    return compare_scene(
        scene_folder / FOLDER,
        scene_folder.name,
        files,
        package=NOVEL_LIGHTS,
        label=f"mini/{scene_folder.name}/{FOLDER}",
    )


def load_condition(scene_folder: Path, condition: str) -> NovelCondition:
    """One condition of a scene's ground truth under new illumination (installed first for a mini
    scene, `ensure_novel_lights`): its lighting and its frames, frame id -> EXR path, in the scene's
    test order."""
    folder = ensure_novel_lights(Path(scene_folder)) / condition
    if not folder.is_dir():
        present = sorted(path.name for path in folder.parent.iterdir() if path.is_dir())
        raise DatasetError(
            f"no condition {condition!r} here; conditions: {', '.join(present) or 'none'}",
            path=folder,
        )
    frame_ids = scene_test_frames(Path(scene_folder))
    lighting = check_condition(folder, frame_ids)
    return NovelCondition(
        condition, lighting, {frame_id: folder / f"{frame_id}.exr" for frame_id in frame_ids}
    )


def condition_names(scene_folder: Path) -> list[str]:
    """The conditions a scene folder holds (its ``novel_lights`` subfolders; packaged ones first, in
    order), without installing or checking anything (for ``olatbench datasets info``)."""
    folder = Path(scene_folder) / FOLDER
    present = (
        {path.name for path in folder.iterdir() if path.is_dir() and not path.name.startswith(".")}
        if folder.is_dir()
        else set()
    )
    return [name for name in CONDITIONS if name in present] + sorted(present - set(CONDITIONS))


__all__ = [
    "CONDITIONS",
    "FOLDER",
    "MANTISSA_BITS",
    "SPP",
    "NovelCondition",
    "check_condition",
    "compare_novel_lights",
    "condition_lighting",
    "condition_names",
    "ensure_novel_lights",
    "lighting_file",
    "load_condition",
    "mini_scene_name",
    "render_condition",
    "render_novel_lights",
    "scene_test_frames",
]
