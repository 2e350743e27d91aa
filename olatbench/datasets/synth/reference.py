"""The mini suite's reference data: the packaged renders, their hashes, and how a local render
compares.

The package carries, for each mini scene, ``data/mini/<scene>.tar.xz``: every file of the scene as
rendered once by the pinned generator on the reference machine, and ``data/mini_reference.json``:
the sha256 of every one of those files with the generator version, Mitsuba version and variant and
the machine (``made_on``). These renders *are* the mini suite: `unpack_reference` puts a scene's
files into a folder (the caller checks them against the hashes,
`olatbench.datasets.synth.mini.install_reference_scene`), so every machine trains on the same bytes
whatever its CPU does to Mitsuba's arithmetic. A scene rendered here with Mitsuba (``olatbench
datasets synth --mini --render``) is compared with them by `compare_scene`: which files differ and,
over all its images, by how much (max / mean absolute difference in [0, 1] pixel units, alpha
included).

`write_reference` (maintainers, ``--mini --render --write-reference``) replaces both after a
generator or Mitsuba pin change.

The mini suite's ground truth under new illumination (`olatbench.datasets.novel_lights`) is packaged
the same way, by the same functions given its `Package`, `NOVEL_LIGHTS`:
``data/novel_lights/<scene>.tar.xz`` (each condition's folder of the scene) and
``data/novel_lights_reference.json``.
"""

from __future__ import annotations

import json
import tarfile
import tempfile
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.atomic import atomic_path, write_json
from olatbench.datasets.images import read_image

# 2: the whole scenes are packaged (data/mini/<scene>.tar.xz); 1 carried four samples each
REFERENCE_FORMAT = 2
ARCHIVE_SUFFIX = ".tar.xz"


@dataclass(frozen=True)
class Package:
    """One set of packaged reference renders: archives ``<root>/<folder>/<scene>.tar.xz`` of the
    files below ``<scene folder>/<subfolder>``, hashes in ``<root>/<record>``, and which of those
    files are images whose pixels a comparison measures (``images``: (first folder of the relative
    path, or "" for any; file suffix))."""

    folder: str
    subfolder: str
    record: str
    label: str
    images: tuple[tuple[str, str], ...]

    def is_image(self, relpath: str) -> bool:
        """Whether a file of a scene is one of the images a comparison reads."""
        first = relpath.split("/", 1)[0]
        return any(
            (folder in ("", first)) and relpath.endswith(suffix) for folder, suffix in self.images
        )


#: The mini suite: its frames' images (geometry/ holds the diagnostic pass, compared by hash only).
MINI = Package(
    "mini", "", "mini_reference.json", "mini reference", (("train", ".png"), ("test", ".png"))
)
#: The mini scenes' ground truth under new illumination: ``<condition>/<frame_id>.exr`` per scene.
NOVEL_LIGHTS = Package(
    "novel_lights",
    "novel_lights",
    "novel_lights_reference.json",
    "novel-light ground truth",
    (("", ".exr"),),
)


def reference_root() -> Path:
    """The packaged reference folder (``olatbench/datasets/synth/data``)."""
    return Path(str(resources.files("olatbench.datasets.synth") / "data"))


def load_reference(root: Path | None = None, package: Package = MINI) -> dict[str, Any]:
    """The reference record of ``package``: ``{"format", "generator_version", "mitsuba_version",
    "mitsuba_variant", "made_on", "scenes": {name: {"files": {relpath: sha256}}}}``."""
    path = (root or reference_root()) / package.record
    record = json.loads(path.read_text(encoding="utf-8"))
    if record.get("format") != REFERENCE_FORMAT:
        raise ValueError(
            f"{path}: reference format {record.get('format')!r}, expected {REFERENCE_FORMAT}"
        )
    return record


def archive_path(scene: str, root: Path | None = None, package: Package = MINI) -> Path:
    """The packaged archive of one mini scene: ``<root>/<package folder>/<scene>.tar.xz``."""
    return (root or reference_root()) / package.folder / f"{scene}{ARCHIVE_SUFFIX}"


def unpack_reference(
    scene: str, destination: Path, root: Path | None = None, package: Package = MINI
) -> Path:
    """Unpack the packaged renders of ``scene`` into ``destination`` (created; members checked to
    stay inside it, no links). The bytes are not checked here: compare them with the reference
    hashes."""
    from olatbench.datasets.download.archives import extract

    archive = archive_path(scene, root, package)
    if not archive.is_file():
        raise FileNotFoundError(
            f"{archive}: the packaged {package.label} of {scene!r} is missing (a broken "
            "install?); reinstall olatbench, or render the suite: olatbench datasets synth "
            "--mini --render"
        )
    extract(archive, Path(destination))
    return Path(destination)


@dataclass(frozen=True)
class PixelDifference:
    """How much one image differs: absolute differences in [0, 1] units over all channels."""

    path: str
    max_abs: float
    mean_abs: float


@dataclass
class SceneComparison:
    """A rendered scene against its reference: file lists, and the pixel differences of its
    differing images (``images``: how many images were compared; the others are byte-identical);
    ``label`` names it in the summary (default ``mini/<scene>``)."""

    scene: str
    missing: list[str] = field(default_factory=list)
    extra: list[str] = field(default_factory=list)
    differing: list[str] = field(default_factory=list)
    pixels: list[PixelDifference] = field(default_factory=list)
    images: int = 0
    label: str = ""

    @property
    def identical(self) -> bool:
        return not (self.missing or self.extra or self.differing)

    def summary(self, reference: dict[str, Any]) -> str:
        """One plain sentence for logs and the CLI."""
        renderer = f"Mitsuba {reference['mitsuba_version']} {reference['mitsuba_variant']}"
        name = self.label or f"mini/{self.scene}"
        if self.identical:
            return f"{name}: identical to the reference ({renderer})"
        parts = [f"{len(self.differing)} differ"] if self.differing else []
        parts += [f"{len(self.missing)} missing"] if self.missing else []
        parts += [f"{len(self.extra)} extra"] if self.extra else []
        example = (self.differing or self.missing or self.extra)[0]
        text = (
            f"{name}: NOT identical to the reference rendered with {renderer} on "
            f"{reference['made_on']}: files {', '.join(parts)} (e.g. {example})"
        )
        if not self.images:
            return text
        if not self.pixels:
            return text + f"; its {self.images} images are identical"
        worst = max(self.pixels, key=lambda d: d.max_abs)
        mean = sum(d.mean_abs for d in self.pixels) / self.images  # identical images add 0
        return (
            text + f"; {len(self.pixels)} of {self.images} images compared differ: max |Δ| = "
            f"{worst.max_abs:.4g} ({worst.path}), mean |Δ| = {mean:.3g} over all {self.images} "
            "(pixel values in [0, 1])"
        )


def compare_scene(
    folder: Path,
    scene: str,
    files: dict[str, str],
    reference: dict[str, Any] | None = None,
    root: Path | None = None,
    measure_pixels: bool = True,
    package: Package = MINI,
    label: str = "",
) -> SceneComparison:
    """Compare a scene's file hashes (``files``: relpath -> sha256, as in its manifest) with
    ``package``'s reference.

    With ``measure_pixels``, every image present in both is compared: those whose bytes differ are
    read from ``folder`` and from the packaged renders (unpacked into a temporary folder) and their
    pixels compared; without, only hashes are compared.
    """
    reference = reference or load_reference(root, package)
    if scene not in reference["scenes"]:
        raise KeyError(
            f"the {package.label} has no scene {scene!r}; it has {', '.join(reference['scenes'])}"
        )
    expected = reference["scenes"][scene]["files"]
    comparison = SceneComparison(
        scene,
        missing=sorted(set(expected) - set(files)),
        extra=sorted(set(files) - set(expected)),
        differing=sorted(p for p in set(expected) & set(files) if expected[p] != files[p]),
        label=label,
    )
    if not measure_pixels:
        return comparison
    comparison.images = sum(
        1 for relpath in set(expected) & set(files) if package.is_image(relpath)
    )
    differing_images = [relpath for relpath in comparison.differing if package.is_image(relpath)]
    if not differing_images:
        return comparison
    with tempfile.TemporaryDirectory(prefix="olatbench-mini-reference-") as temporary:
        theirs_root = unpack_reference(scene, Path(temporary), root, package)
        for relpath in differing_images:
            ours, theirs = read_image(Path(folder) / relpath), read_image(theirs_root / relpath)
            if ours.shape != theirs.shape:
                comparison.pixels.append(PixelDifference(relpath, float("inf"), float("inf")))
                continue
            difference = np.abs(ours - theirs)
            comparison.pixels.append(
                PixelDifference(relpath, float(difference.max()), float(difference.mean()))
            )
    return comparison


def _write_archive(scene_folder: Path, files: dict[str, str], target: Path) -> None:
    """``files`` of ``scene_folder`` into an xz tar at ``target``, byte-reproducible: sorted
    members, no owner, time 0, mode 644 (so writing the same renders again gives the same
    archive)."""
    with atomic_path(target) as temporary, tarfile.open(temporary, "w:xz", preset=9) as bundle:
        for relpath in sorted(files):
            info = bundle.gettarinfo(str(scene_folder / relpath), arcname=relpath)
            info.uid = info.gid = 0
            info.uname = info.gname = ""
            info.mtime = 0
            info.mode = 0o644
            with open(scene_folder / relpath, "rb") as handle:
                bundle.addfile(info, handle)


def write_reference(
    suite_root: Path,
    scenes: dict[str, dict[str, str]],
    metadata: dict[str, Any],
    out: Path | None = None,
    package: Package = MINI,
) -> Path:
    """Make the renders below ``suite_root`` the reference of ``package``: one archive per scene and
    the hashes (``scenes``: name -> manifest files, relative to
    ``suite_root/<name>/<package.subfolder>``), written below ``out``
    (default: the package's `reference_root`).

    ``metadata`` holds ``generator_version``, ``mitsuba_version``, ``mitsuba_variant`` and
    ``made_on``. Run once by a maintainer when the generator or the pinned Mitsuba changes
    (``olatbench datasets synth --mini --render --write-reference``); the result is committed as
    package data.
    """
    out = out or reference_root()
    record = {"format": REFERENCE_FORMAT, **metadata, "scenes": {}}
    for scene, files in scenes.items():
        _write_archive(
            Path(suite_root) / scene / package.subfolder, files, archive_path(scene, out, package)
        )
        record["scenes"][scene] = {"files": files}
    write_json(out / package.record, record)
    return out / package.record
