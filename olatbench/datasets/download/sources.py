"""Where each suite's scenes are published, as data.

A `Source` is either *hosted* on a Hugging Face dataset repository (its file list, sizes and
sha256 come from the Hub's tree API at download time, so nothing is guessed here), served
from a *mirror* folder the user names, or *manual* (printed instructions). Scene names are the
suites' canonical names; ``archive_prefix`` selects the repository files of one scene.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

HF_ENDPOINT = "https://huggingface.co"


@dataclass(frozen=True)
class Source:
    """One way to obtain one scene.

    ``kind``: ``"hf"`` (Hugging Face dataset ``repo``; files under ``prefix`` whose name starts
    with ``archive_prefix``), ``"mirror"`` (files ``archives`` under a user-given ``--mirror`` URL),
    or ``"manual"`` (``instructions`` only). ``archives`` lists archive names; several names that
    end in ``.001``, ``.002``… are the parts of one archive, joined in order before unpacking.
    """

    name: str
    kind: Literal["hf", "mirror", "manual"]
    repo: str = ""
    prefix: str = ""
    archive_prefix: str = ""
    archives: tuple[str, ...] = ()
    instructions: str = ""
    folder_aliases: tuple[str, ...] = field(default_factory=tuple)


GS3_REPO = "gsrelight/gsrelight-data"

NRHINTS_PAGE = "https://nrhints.github.io/"
NRHINTS_MANUAL = (
    "The NRHints project publishes one zip per real scene (Pikachu in two parts) behind the 'Data' link of "
    f"{NRHINTS_PAGE}. Download them into one folder and run: olatbench datasets download nrhints "
    "--source nrhints-project --mirror file:///path/to/that/folder  (or serve the folder over HTTP and pass its URL)."
)
SSSGS_MANUAL = (
    "The SSS-GS synthetic scenes are published by the SSS-GS authors (Dihlmann et al., NeurIPS 2024) on their "
    "project page. Download the scene archives into one folder and run: olatbench datasets download sssgs "
    "--source sssgs-mirror --mirror file:///path/to/that/folder"
)
SSDGS_MANUAL = (
    "The SSD-GS authors' converted copies are shared on request through their project page; olatbench reads the "
    "original formats directly, so use the 'gs3-hf' or 'nrhints-project' sources instead."
)

NRHINTS_SCENES = ("Cat", "CatSmall", "CupFabric", "Fish", "FurScene", "Pikachu", "Pixiu")
NRHINTS_FOLDERS = {"CatSmall": ("Cat_on_Decor",), "FurScene": ("Cluttered",), "CupFabric": ("Cup-Fabric",)}
GS3_SCENES = ("Translucent", "AnisoMetal", "Drums", "FurBall", "Hotdog", "Lego")
SSSGS_SCENES = ("Bunny", "Candle", "Dragon", "Soap", "Statue")


def _nrhints_archives(scene: str) -> tuple[str, ...]:
    folder = NRHINTS_FOLDERS.get(scene, (scene,))[0]
    return (f"{folder}.zip.001", f"{folder}.zip.002") if scene == "Pikachu" else (f"{folder}.zip",)


SOURCES: dict[str, dict[str, list[Source]]] = {
    "nrhints": {
        scene: [
            Source("gs3-hf", "hf", repo=GS3_REPO, prefix="", archive_prefix=NRHINTS_FOLDERS.get(scene, (scene,))[0],
                   folder_aliases=NRHINTS_FOLDERS.get(scene, ())),
            Source("nrhints-project", "mirror", archives=_nrhints_archives(scene), instructions=NRHINTS_MANUAL,
                   folder_aliases=NRHINTS_FOLDERS.get(scene, ())),
        ]
        for scene in NRHINTS_SCENES
    },
    "gs3": {
        scene: [Source("gs3-hf", "hf", repo=GS3_REPO, prefix="", archive_prefix=scene.lower())]
        for scene in GS3_SCENES
    },
    "sssgs": {
        scene: [Source("sssgs-mirror", "mirror", archives=(f"{scene.lower()}.zip",), instructions=SSSGS_MANUAL),
                Source("ssdgs-converted", "manual", instructions=SSDGS_MANUAL)]
        for scene in SSSGS_SCENES
    },
}


def sources_for(suite: str, scene: str, source: str | None = None) -> list[Source]:
    """The sources of one scene, the named one only when ``source`` is given; `KeyError` lists the choices."""
    if suite not in SOURCES:
        raise KeyError(f"no download sources for suite '{suite}'; known: {', '.join(sorted(SOURCES))}")
    scenes = SOURCES[suite]
    if scene not in scenes:
        raise KeyError(f"suite '{suite}' has no scene '{scene}'; known: {', '.join(scenes)}")
    candidates = scenes[scene]
    if source is None:
        return candidates
    chosen = [s for s in candidates if s.name == source]
    if not chosen:
        raise KeyError(f"scene '{scene}' has no source '{source}'; known: {', '.join(s.name for s in candidates)}")
    return chosen
