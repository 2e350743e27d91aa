"""Is this machine's ``mini`` data the reference data? Packaged hashes, and pixel differences when not.

The package carries ``data/mini_reference.json``: for each mini scene, the sha256 of every file as
rendered by the pinned generator (the Mitsuba version and variant it records), and a few sample
images (``data/mini_reference/<scene>/<split>/<frame>.png``, full resolution). `compare_scene` says
whether a rendered scene is byte-identical to the reference and, if not, which files differ and by
how much on the sampled images (max / mean absolute difference in [0, 1] pixel units, alpha included).

The reference was made by `write_reference` on one machine (its ``made_on`` field); a user whose renders
differ can tell from ``mitsuba_version`` / ``mitsuba_variant`` whether the renderer differs.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.atomic import write_json
from olatbench.datasets.images import read_image

REFERENCE_FORMAT = 1
#: Sampled images per scene whose pixels the package carries (the first two of each split).
SAMPLES_PER_SPLIT = 2


def reference_root() -> Path:
    """The packaged reference folder (``olatbench/datasets/synth/data``)."""
    return Path(str(resources.files("olatbench.datasets.synth") / "data"))


def load_reference(root: Path | None = None) -> dict[str, Any]:
    """The reference record: ``{"format", "generator_version", "mitsuba_version", "mitsuba_variant",
    "made_on", "scenes": {name: {"files": {relpath: sha256}, "samples": [relpath, ...]}}}``."""
    path = (root or reference_root()) / "mini_reference.json"
    record = json.loads(path.read_text(encoding="utf-8"))
    if record.get("format") != REFERENCE_FORMAT:
        raise ValueError(f"{path}: reference format {record.get('format')!r}, expected {REFERENCE_FORMAT}")
    return record


@dataclass(frozen=True)
class PixelDifference:
    """How much one sampled image differs: absolute differences in [0, 1] units over all channels."""

    path: str
    max_abs: float
    mean_abs: float


@dataclass
class SceneComparison:
    """A rendered scene against its reference: file lists and pixel differences of the sampled images."""

    scene: str
    missing: list[str] = field(default_factory=list)
    extra: list[str] = field(default_factory=list)
    differing: list[str] = field(default_factory=list)
    pixels: list[PixelDifference] = field(default_factory=list)

    @property
    def identical(self) -> bool:
        return not (self.missing or self.extra or self.differing)

    def summary(self, reference: dict[str, Any]) -> str:
        """One plain sentence (two when pixels differ) for logs and the CLI."""
        renderer = f"Mitsuba {reference['mitsuba_version']} {reference['mitsuba_variant']}"
        if self.identical:
            return f"mini/{self.scene}: identical to the reference ({renderer})"
        parts = [f"{len(self.differing)} differ"] if self.differing else []
        parts += [f"{len(self.missing)} missing"] if self.missing else []
        parts += [f"{len(self.extra)} extra"] if self.extra else []
        text = (f"mini/{self.scene}: NOT identical to the reference rendered with {renderer}: files "
                f"{', '.join(parts)} (e.g. {(self.differing or self.missing or self.extra)[0]})")
        if self.pixels:
            worst = max(self.pixels, key=lambda d: d.max_abs)
            mean = float(np.mean([d.mean_abs for d in self.pixels]))
            text += (f"; on {len(self.pixels)} sampled images max |Δ| = {worst.max_abs:.4f} ({worst.path}), "
                     f"mean |Δ| = {mean:.5f} (pixel values in [0, 1])")
        return text


def compare_scene(folder: Path, scene: str, files: dict[str, str], reference: dict[str, Any] | None = None,
                  root: Path | None = None, measure_pixels: bool = True) -> SceneComparison:
    """Compare a scene's file hashes (``files``: relpath -> sha256, as in its manifest) with the reference.

    With ``measure_pixels``, sampled images that differ are read from ``folder`` and compared pixel by pixel
    with the packaged copies below ``root`` (default `reference_root`); without, only hashes are compared.
    """
    reference = reference or load_reference(root)
    if scene not in reference["scenes"]:
        raise KeyError(f"the mini reference has no scene {scene!r}; it has {', '.join(reference['scenes'])}")
    expected = reference["scenes"][scene]["files"]
    comparison = SceneComparison(scene,
                                 missing=sorted(set(expected) - set(files)),
                                 extra=sorted(set(files) - set(expected)),
                                 differing=sorted(p for p in set(expected) & set(files) if expected[p] != files[p]))
    if not measure_pixels:
        return comparison
    samples = (root or reference_root()) / "mini_reference" / scene
    for relpath in reference["scenes"][scene]["samples"]:
        if relpath in comparison.differing:
            ours, theirs = read_image(Path(folder) / relpath), read_image(samples / relpath)
            if ours.shape != theirs.shape:
                comparison.pixels.append(PixelDifference(relpath, float("inf"), float("inf")))
                continue
            difference = np.abs(ours - theirs)
            comparison.pixels.append(PixelDifference(relpath, float(difference.max()), float(difference.mean())))
    return comparison


def _sample_paths(files: dict[str, str]) -> list[str]:
    """The first `SAMPLES_PER_SPLIT` PNG images of each split folder (``train/``, ``test/``)."""
    samples = []
    for split in ("train", "test"):
        images = sorted(p for p in files if p.startswith(f"{split}/") and p.endswith(".png"))
        samples += images[:SAMPLES_PER_SPLIT]
    return samples


def write_reference(suite_root: Path, scenes: dict[str, dict[str, str]], metadata: dict[str, Any],
                    out: Path | None = None) -> Path:
    """Write the reference (hashes of ``scenes``: name -> manifest files, and sample images) below ``out``.

    ``metadata`` holds ``generator_version``, ``mitsuba_version``, ``mitsuba_variant`` and ``made_on``.
    Run once by a maintainer when the generator or the pinned Mitsuba changes (``olatbench datasets synth
    --mini --write-reference``); the result is committed as package data.
    """
    out = out or reference_root()
    record = {"format": REFERENCE_FORMAT, **metadata, "scenes": {}}
    for scene, files in scenes.items():
        samples = _sample_paths(files)
        record["scenes"][scene] = {"files": files, "samples": samples}
        for relpath in samples:
            target = out / "mini_reference" / scene / relpath
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(Path(suite_root) / scene / relpath, target)
    write_json(out / "mini_reference.json", record)
    return out / "mini_reference.json"
