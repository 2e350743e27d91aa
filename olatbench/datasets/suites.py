"""Benchmark suites: the paper's scene lists and settings, so ``--suite nrhints`` means the paper's setting.

Sources: the SSD-GS paper (Sec. 5 and appendix) and ``ssdgs_iclr2026.csv``. NRHints scenes are 512² or
1024² (``resolution=None`` keeps each scene's native size); GS³ is 512²; SSS-GS is the public 256²
down-scaled release. Folder aliases map the names found on disk to the canonical names of the paper.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from olatbench.datasets.errors import DatasetError


def _snake(name: str) -> str:
    """``AnisoMetal`` -> ``aniso_metal``."""
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def _default_aliases(scenes: tuple[str, ...], extra: dict[str, str] | None = None) -> dict[str, str]:
    """Lower-case and snake_case spellings of each canonical name, plus ``extra``."""
    aliases = {}
    for scene in scenes:
        for spelling in {scene.lower(), _snake(scene)} - {scene}:
            aliases[spelling] = scene
    aliases.update(extra or {})
    return aliases


@dataclass(frozen=True)
class Suite:
    """A named benchmark setting: which scenes, how they are read, trained and scored."""

    name: str
    format: str
    scenes: tuple[str, ...]
    aliases: dict[str, str] = field(default_factory=dict)  # folder name -> canonical scene name
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    resolution: tuple[int, int] | None = None  # (width, height) or native
    iterations: int = 100_000
    protocol: str = "ssdgs"
    train_split: str = "train"
    test_split: str = "test"
    generator: str | None = None  # "module:function" creating the data on first use
    generator_root: str | None = None  # "module:function" returning where the generator keeps its data

    @property
    def colourspace(self) -> str:
        """The space methods are trained and scored in: the format's (`formats.display_colourspace`)."""
        from olatbench.datasets.formats import display_colourspace

        return display_colourspace(self.format)

    def canonical(self, folder: str) -> str | None:
        """The canonical scene name of a folder name, or None when it is not in this suite."""
        if folder in self.scenes:
            return folder
        return self.aliases.get(folder) or self.aliases.get(folder.lower())

    def scene_path(self, data_root: str | Path, scene: str) -> Path:
        """The folder of ``scene`` below ``data_root``: by canonical name or any alias."""
        data_root = Path(data_root)
        canonical = self.canonical(scene) or scene
        if canonical not in self.scenes:
            raise DatasetError(f"suite '{self.name}' has no scene '{scene}'; scenes: {', '.join(self.scenes)}",
                               path=data_root)
        candidates = [canonical, *sorted(a for a, target in self.aliases.items() if target == canonical)]
        for name in candidates:
            if (data_root / name).is_dir():
                return data_root / name
        raise DatasetError(f"scene '{canonical}' of suite '{self.name}' not found; looked for folders "
                           f"{', '.join(candidates)}. Try: olatbench datasets download {self.name}",
                           path=data_root)


_NRHINTS_SCENES = ("Cat", "CatSmall", "CupFabric", "Fish", "FurScene", "Pikachu", "Pixiu")
_GS3_SCENES = ("Translucent", "AnisoMetal", "Drums", "FurBall", "Hotdog", "Lego")
_SSSGS_SCENES = ("Bunny", "Candle", "Dragon", "Soap", "Statue")
_MINI_SCENES = ("diffuse_shadow", "aniso_metal", "translucent")

SUITES: dict[str, Suite] = {
    "nrhints": Suite(
        name="nrhints", format="nrhints", scenes=_NRHINTS_SCENES,
        aliases=_default_aliases(_NRHINTS_SCENES, {"Cat_on_Decor": "CatSmall", "Cluttered": "FurScene",
                                                   "Cup-Fabric": "CupFabric"}),
        background=(0.0, 0.0, 0.0), resolution=None, iterations=100_000, protocol="ssdgs"),
    "gs3": Suite(
        name="gs3", format="gs3", scenes=_GS3_SCENES, aliases=_default_aliases(_GS3_SCENES),
        background=(1.0, 1.0, 1.0), resolution=(512, 512), iterations=100_000,
        protocol="ssdgs"),
    "sssgs": Suite(
        name="sssgs", format="sssgs", scenes=_SSSGS_SCENES,
        aliases=_default_aliases(_SSSGS_SCENES, {f"{s.lower()}_small": s for s in _SSSGS_SCENES}),
        background=(0.0, 0.0, 0.0), resolution=(256, 256), iterations=60_000, protocol="ssdgs"),
    "mini": Suite(
        name="mini", format="nrhints", scenes=_MINI_SCENES, aliases={}, background=(0.0, 0.0, 0.0),
        resolution=None, iterations=3000, protocol="olatbench-v1",
        generator="olatbench.datasets.synth.mini:ensure_mini_suite",
        generator_root="olatbench.datasets.synth.mini:default_root"),
}


def suite_names() -> list[str]:
    """Names of the built-in suites."""
    return list(SUITES)


def get_suite(name: str) -> Suite:
    """The suite called ``name``; a `DatasetError` listing the known suites otherwise."""
    try:
        return SUITES[name]
    except KeyError:
        raise DatasetError(f"unknown suite '{name}'; known suites: {', '.join(SUITES)}") from None


def canonical_scene_name(folder: str, format: str | None = None) -> str:
    """The paper's name of a scene folder (e.g. ``Cat_on_Decor`` -> ``CatSmall``); the folder name otherwise."""
    for suite in SUITES.values():
        if format is None or suite.format == format:
            canonical = suite.canonical(folder)
            if canonical is not None:
                return canonical
    return folder
