"""The ``mini`` suite: three small OLAT scenes, the same bytes on every machine, installed on first
use and cached.

``ensure_mini_suite()`` returns a folder holding ``diffuse_shadow/``, ``aniso_metal/`` and
``translucent/`` in NRHints format (80×80, 100 train + 20 test frames, test lights novel). The
scenes are the packaged reference renders (`olatbench.datasets.synth.reference`): each is unpacked
from the package, every file checked against the sha256 in ``mini_reference.json``, so the data do
not depend on what a CPU does to Mitsuba's arithmetic, and Mitsuba is not needed. Rendering with
Mitsuba is an explicit choice (``render=True``, ``olatbench datasets synth --mini --render``; by
default into `default_render_root`): the result is compared with the reference and the log says how
it differs; `data_matches_reference` tells the runner.

Each scene folder carries a ``manifest.json`` with the recipe and the sha256 of every file (but
those of its ``novel_lights/`` folder, the ground truth under new illumination, installed and
checked apart with its own manifest by `olatbench.datasets.novel_lights`); a scene is reused only
when its recipe is today's and every hash matches (and, for the installed suite, the files are the
reference's), otherwise it is installed (or rendered) again. Scenes are written into a temporary
sibling folder and renamed into place, so an interruption never leaves half a scene; a lock file
serialises concurrent callers (several runner processes may start at once).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import os
import shutil
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from olatbench.atomic import write_json
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.synth.backend import pinned_variant
from olatbench.datasets.synth.generate import GENERATOR_VERSION, generate
from olatbench.datasets.synth.recipe import RECIPES, Recipe
from olatbench.datasets.synth.reference import (
    MINI,
    NOVEL_LIGHTS,
    Package,
    SceneComparison,
    archive_path,
    compare_scene,
    load_reference,
    unpack_reference,
)

MINI_SCENES = ("diffuse_shadow", "aniso_metal", "translucent")
#: The Mitsuba variant of the mini suite everywhere: ``llvm_ad_rgb`` (where a machine has LLVM)
#: renders other pixels than ``scalar_rgb``, so a probed variant would make the data depend on the
#: machine.
MINI_VARIANT = "scalar_rgb"
MANIFEST = "manifest.json"
#: Folders of a scene installed and checked apart, each with its own manifest (and their transient
#: partial and stale copies, `publish`): not among the scene's files.
APART = (
    NOVEL_LIGHTS.subfolder,
    f".{NOVEL_LIGHTS.subfolder}.partial",
    f".{NOVEL_LIGHTS.subfolder}.stale",
)
log = logging.getLogger(__name__)


def mini_recipes() -> dict[str, Recipe]:
    """The recipes of the mini suite (the built-in recipes of the same names, at their defaults)."""
    return {name: RECIPES[name] for name in MINI_SCENES}


def _cache() -> Path:
    return Path(os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")) / "olatbench"


def default_root() -> Path:
    """Where the suite is installed: ``$XDG_CACHE_HOME/olatbench/mini``
    (default ``~/.cache/olatbench/mini``)."""
    return _cache() / "mini"


def default_render_root() -> Path:
    """Where ``render=True`` puts this machine's renders:
    ``$XDG_CACHE_HOME/olatbench/mini-rendered`` (apart from the installed suite, which runs use
    unless given ``--data-root``)."""
    return _cache() / "mini-rendered"


def file_hashes(folder: Path, exclude: Sequence[str] = ()) -> dict[str, str]:
    """sha256 of every file below ``folder`` except the manifest and what lies in its top-level
    folders named in ``exclude``, keyed by POSIX relative path."""
    hashes = {}
    for path in sorted(folder.rglob("*")):
        if (
            path.is_file()
            and path.name != MANIFEST
            and path.relative_to(folder).parts[0] not in exclude
        ):
            hashes[path.relative_to(folder).as_posix()] = hashlib.sha256(
                path.read_bytes()
            ).hexdigest()
    return hashes


def _expected_header(recipe: Recipe) -> dict[str, Any]:
    return {
        "generator_version": GENERATOR_VERSION,
        "recipe": json.loads(json.dumps(recipe.to_dict())),
    }


def scene_is_valid(folder: Path, recipe: Recipe) -> tuple[bool, str]:
    """(valid, reason): the manifest exists, names this recipe and generator, and every hash
    matches."""
    manifest_path = folder / MANIFEST
    if not manifest_path.is_file():
        return False, "no manifest"
    try:
        manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as error:
        return False, f"unreadable manifest ({error})"
    expected = _expected_header(recipe)
    if any(manifest.get(key) != value for key, value in expected.items()):
        return False, "made by another recipe or generator version"
    if manifest.get("files") != file_hashes(folder, APART):
        return False, "files differ from the manifest (missing, extra or modified)"
    return True, "ok"


@contextlib.contextmanager
def locked(root: Path) -> Iterator[None]:
    """An exclusive lock on ``root/.lock`` where the platform has ``fcntl`` (no-op elsewhere)."""
    root.mkdir(parents=True, exist_ok=True)
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    with open(root / ".lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


def publish(root: Path, name: str, partial: Path) -> Path:
    """Rename a finished ``partial`` scene folder to ``root/name``, replacing what was there."""
    final = root / name
    if final.exists():
        stale = root / f".{name}.stale"
        shutil.rmtree(stale, ignore_errors=True)
        os.replace(final, stale)
        shutil.rmtree(stale, ignore_errors=True)
    os.replace(partial, final)
    return final


def render_mini_scene(root: Path, name: str, recipe: Recipe, progress: bool = True) -> Path:
    """Render one scene into ``root/.<name>.partial`` with its manifest, then rename it to
    ``root/name``."""
    partial = root / f".{name}.partial"
    shutil.rmtree(partial, ignore_errors=True)
    with pinned_variant(MINI_VARIANT):
        generate(recipe, partial, "nrhints", progress=progress)
    write_json(
        partial / MANIFEST, {**_expected_header(recipe), "files": file_hashes(partial, APART)}
    )
    return publish(root, name, partial)


def unpack_verified(
    name: str, partial: Path, reference: dict[str, Any], package: Package = MINI
) -> dict[str, str]:
    """Unpack scene ``name``'s packaged archive of ``package`` into the fresh folder ``partial`` and
    check every file against the reference hashes; return them (relpath -> sha256). A `DatasetError`
    naming the archive (and a file that does not match) otherwise, ``partial`` removed."""
    shutil.rmtree(partial, ignore_errors=True)
    archive = archive_path(name, package=package)
    try:
        unpack_reference(name, partial, package=package)
    except ValueError as error:  # a damaged or unsafe archive (the downloader's extract names it)
        shutil.rmtree(partial, ignore_errors=True)
        raise DatasetError(
            f"cannot unpack the packaged {package.label} ({error}); reinstall olatbench",
            path=archive,
        ) from None
    files, expected = file_hashes(partial), reference["scenes"][name]["files"]
    if files != expected:
        wrong = sorted(set(files) ^ set(expected)) or sorted(
            p for p in files if files[p] != expected[p]
        )
        shutil.rmtree(partial, ignore_errors=True)
        raise DatasetError(
            f"the packaged {package.label} does not match the hashes in {package.record} "
            f"({len(wrong)} files, e.g. {wrong[0]}); reinstall olatbench",
            path=archive,
        )
    return files


def install_reference_scene(
    root: Path, name: str, recipe: Recipe, reference: dict[str, Any]
) -> Path:
    """Unpack the packaged renders of scene ``name`` into ``root/.<name>.partial``, check every file
    against the reference hashes and the scene's ``synth.json`` against ``recipe`` and this
    generator, write the manifest and rename the folder to ``root/name``. A `DatasetError` naming
    the archive when anything does not match."""
    partial = root / f".{name}.partial"
    archive = archive_path(name)
    files = unpack_verified(name, partial, reference)
    made_by = json.loads((partial / "synth.json").read_text(encoding="utf-8"))
    header = _expected_header(recipe)
    if any(made_by.get(key) != value for key, value in header.items()):
        shutil.rmtree(partial, ignore_errors=True)
        raise DatasetError(
            "the packaged renders were made by generator version "
            f"{made_by.get('generator_version')} with another recipe or generator than this "
            f"olatbench's (version {GENERATOR_VERSION}); render the suite with: olatbench "
            "datasets synth --mini --render",
            path=archive,
        )
    write_json(partial / MANIFEST, {**header, "files": files})
    return publish(root, name, partial)


def ensure_mini_suite(
    root: Path | None = None,
    progress: bool = True,
    recipes: dict[str, Recipe] | None = None,
    scenes: Sequence[str] | None = None,
    compare: bool = True,
    render: bool = False,
) -> Path:
    """Make sure the mini suite exists and is intact below ``root``; return ``root``.

    By default the scenes are the packaged reference renders, installed into ``root``
    (default `default_root`) where missing, damaged or not the reference's bytes. ``render``: render
    them with Mitsuba instead (into ``root``, default `default_render_root`), where missing, changed
    or corrupt, and log each one's comparison with the reference (``compare``; off only while
    writing a new reference). ``scenes``: only these (default: all), so a run on one scene prepares
    one. ``recipes`` replaces the suite's recipes (tests use tiny ones) and implies rendering: only
    the built-in recipes have packaged renders.
    """
    recipes_are_builtin = recipes is None
    render = render or not recipes_are_builtin
    root = Path(root) if root is not None else default_render_root() if render else default_root()
    recipes = mini_recipes() if recipes is None else recipes
    if scenes is not None:
        unknown = sorted(set(scenes) - set(recipes))
        if unknown:
            raise KeyError(
                f"the mini suite has no scene {', '.join(unknown)}; scenes: {', '.join(recipes)}"
            )
        recipes = {name: recipe for name, recipe in recipes.items() if name in scenes}
    reference = load_reference() if recipes_are_builtin and (compare or not render) else None
    rendered = set()
    with locked(root):
        for name, recipe in recipes.items():
            valid, reason = scene_is_valid(root / name, recipe)
            if not render:
                if valid and manifest_files(root / name) == reference["scenes"][name]["files"]:
                    continue
                if (root / name).exists():
                    log.warning(
                        "mini suite: replacing %s with the packaged reference (%s)",
                        root / name,
                        reason
                        if not valid
                        else "this machine's renders, not the reference's bytes",
                    )
                install_reference_scene(root, name, recipe, reference)
                log.info(
                    "mini/%s: installed the packaged reference renders into %s", name, root / name
                )
                continue
            if valid:
                continue
            if (root / name).exists():
                log.warning("mini suite: re-rendering %s (%s)", root / name, reason)
            render_mini_scene(root, name, recipe, progress=progress)
            rendered.add(name)
    if render and compare and recipes_are_builtin:
        for name in recipes:
            comparison = compare_with_reference(root / name, reference)
            if not comparison.identical:
                log.warning("%s", comparison.summary(reference))
            # said once, when the scene is made; results.json records it always
            elif name in rendered and progress:
                from olatbench.progress import progress_write

                progress_write(comparison.summary(reference))
            else:
                log.info("%s", comparison.summary(reference))
    return root


def manifest_files(folder: Path) -> dict[str, str] | None:
    """The ``files`` (relpath -> sha256) of a scene's manifest, or None when it is missing or
    unreadable."""
    try:
        return json.loads((Path(folder) / MANIFEST).read_text(encoding="utf-8"))["files"]
    except (OSError, ValueError, KeyError):
        return None


def compare_with_reference(
    folder: Path, reference: dict[str, Any] | None = None
) -> SceneComparison:
    """A rendered mini scene (``folder``, named after its scene, with its manifest) against the
    reference."""
    files = manifest_files(folder)
    if files is None:
        raise FileNotFoundError(
            f"{Path(folder) / MANIFEST}: no readable manifest; render the scene first"
        )
    return compare_scene(Path(folder), Path(folder).name, files, reference)


def data_matches_reference(folder: str | Path) -> bool | None:
    """Whether a mini scene's files are byte-identical to the packaged reference
    (None: not a mini scene).

    Reads the scene's manifest (hashes written when it was rendered and checked on every use), so it
    costs one small JSON read.
    """
    folder = Path(folder)
    files = manifest_files(folder)
    if folder.name not in MINI_SCENES or files is None:
        return None
    return compare_scene(folder, folder.name, files, measure_pixels=False).identical
