"""What a format says of the suites of its scenes (`SuiteDefaults`): the paper's scene names and
folder aliases, and the resolution, training length and metric protocol its scenes are run with (the
background is each scene's own, set by the format's reader: ``Frame.background``).

Each format module declares its ``SUITE_DEFAULTS``; `olatbench.datasets.suites` builds the paper's
suite of the format from it and gives a suite of one's own folders of the format its iterations and
protocol, and the format's reader names a scene folder with `SuiteDefaults.canonical`. A leaf of the
formats package: suites import formats, never the other way round.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, field


def snake_case(name: str) -> str:
    """``AnisoMetal`` -> ``aniso_metal``."""
    return re.sub(r"(?<=[a-z0-9])(?=[A-Z])", "_", name).lower()


def default_aliases(
    scenes: tuple[str, ...], extra: Mapping[str, str] | None = None
) -> dict[str, str]:
    """Lower-case and snake_case spellings of each canonical name, plus ``extra``."""
    aliases = {}
    for scene in scenes:
        for spelling in {scene.lower(), snake_case(scene)} - {scene}:
            aliases[spelling] = scene
    aliases.update(extra or {})
    return aliases


def canonical_name(folder: str, scenes: tuple[str, ...], aliases: Mapping[str, str]) -> str | None:
    """The canonical scene name of a folder name among ``scenes`` (by name or alias, the alias also
    in lower case), or None."""
    if folder in scenes:
        return folder
    return aliases.get(folder) or aliases.get(folder.lower())


@dataclass(frozen=True)
class SuiteDefaults:
    """A format's suite settings: ``scenes`` (the paper's canonical names, in its order; empty for a
    format the paper does not use), ``aliases`` (folder name -> canonical name), ``resolution``
    ((width, height), None: each scene's own), ``iterations`` and ``protocol``
    (a metric protocol id)."""

    scenes: tuple[str, ...] = ()
    aliases: Mapping[str, str] = field(default_factory=dict)
    resolution: tuple[int, int] | None = None
    iterations: int = 100_000
    protocol: str = "ssdgs"

    def canonical(self, folder: str) -> str | None:
        """The paper's name of a scene folder of this format, or None when the paper has no such
        scene."""
        return canonical_name(folder, self.scenes, self.aliases)
