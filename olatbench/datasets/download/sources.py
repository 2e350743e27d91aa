"""Where each suite's scenes are published, as data.

A `Source` is one way to obtain one scene:

- ``"hf"``: a Hugging Face dataset repository at a fixed revision (a full commit id, or a commit-id
  prefix looked up in the history of ``main`` at download time). The file list, sizes and sha256
  come from the Hub's tree API at download time (every page of it); ``files`` names the exact
  repository paths of the scene's archive, or, where the exact names are not published, ``pattern``
  (a glob) selects them. The Hub is ``$HF_ENDPOINT`` when set (else ``https://huggingface.co``), and
  ``$HF_TOKEN``, when set, is sent to it as ``Authorization: Bearer``.
- ``"url"``: archives under ``base_url`` (``<base_url>/<file>``); no published hashes, so the sha256
  is recorded the first time and checked on every later download. With an empty ``base_url`` the
  files come only from a folder the user names with ``--mirror``.
- ``"manual"``: printed ``instructions`` only.

``--mirror`` replaces the host of any source (the Hub endpoint, or ``base_url``), so a local copy
or a test server can stand in for it. Every location below was read in an official source, cited
next to it; nothing here is a guessed URL.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from olatbench.datasets.suites import SUITES

# the default; $HF_ENDPOINT replaces it, --mirror replaces both
HF_ENDPOINT = "https://huggingface.co"


@dataclass(frozen=True)
class Source:
    """One way to obtain one scene (see the module docstring for the kinds).

    ``files``: repository paths (``hf``) or names under ``base_url`` (``url``); several names ending
    in ``.001``, ``.002``… are the parts of one archive, joined in order before unpacking.
    """

    name: str
    kind: Literal["hf", "url", "manual"]
    files: tuple[str, ...] = ()
    repo: str = ""
    revision: str = "main"  # hf: a full commit id, or a prefix of one in the history of main
    pattern: str = ""
    base_url: str = ""
    instructions: str = ""


# --- NRHints (Zeng et al., SIGGRAPH 2023) ---------------------------------------------------------
# Default: the GS³ re-pack (gs3-hf, below), the copy SSD-GS trains on (the SSD-GS paper evaluates on
# the GS³ authors' release of the NRHints scenes). Whether the NRHints authors' own zips hold the
# same train/test frames could not be checked here (no network); until it is, the paper's copy comes
# first and the authors' zips second. The NRHints authors' own per-scene zips: Read in
# iamNCJ/NRHints README.md ("Data and Models" table, commit
# cd406d699f21c0f3d027a3e9f39a7e268bc0ca24) and scripts/download_data.sh
# (commit 06d0a89a467ace59771112931fa9972f60fd3350):
#   https://igpublicshare.z20.web.core.windows.net/NRHints/Data/Real/<Scene>.zip
# for Cat, FurScene, Pixiu, Fish, CatSmall, CupFabric and Pikachu (Pikachu is one zip there, not two
# parts). Each zip unpacks to a folder of the same name (scripts/train_real.sh reads Real/<Scene>/).
NRHINTS_BASE_URL = "https://igpublicshare.z20.web.core.windows.net/NRHints/Data/Real"

# --- GS³ (Bi et al., SIGGRAPH Asia 2024): Hugging Face dataset gsrelight/gsrelight-data -----------
# The repository is named by the GS³ README ("huggingface-cli download --repo-type dataset
# gsrelight/gsrelight-data"). Its file names were read on the Hub's own pages: tree
# huggingface.co/datasets/gsrelight/gsrelight-data/tree/78df91b8153db055a0119707f2b3c049cd316690/
# Synthetic (commit f12915d "Upload 6 files":
# Synthetic/{AnisoMetal,Drums,FurBall,Hotdog,Lego,Translucent}.zip) and
# .../tree/e855a9af9b855222894ee7a82098d518f6d5c6b1/NRHints (commit a6d7795 "Upload 7 files":
# NRHints/{Cat,Cat_on_Decor,Cluttered,Cup-Fabric,Fish,Pikachu,Pixiu}.zip). The revision is pinned to
# ac856efb0cf970f7fd4ea5fc490bd109122ffdb2 (main's history; later commits only edit README.md),
# so the sha256 the Hub reports for these files cannot change under a benchmark.
GS3_REPO = "gsrelight/gsrelight-data"
GS3_REVISION = "ac856efb0cf970f7fd4ea5fc490bd109122ffdb2"
GS3_NRHINTS_FOLDERS = {
    "CatSmall": "Cat_on_Decor",
    "FurScene": "Cluttered",
    "CupFabric": "Cup-Fabric",
}

# --- SSS-GS (Dihlmann et al., NeurIPS 2024): Hugging Face dataset CGTuebingen/SSS-GS --------------
# The released cgtuebingen/SSS-GS README.md (section "Dataset") names the dataset
# huggingface.co/datasets/CGTuebingen/SSS-GS and says to "unpack the tar files"; the dataset card
# (huggingface.co/datasets/CGTuebingen/SSS-GS/blob/main/README.md, revision 355a987) lays the public
# down-scaled synthetic scenes out as synthetic/<scene>_small/transforms_{train,test,eval}.json. The
# exact archive names were NOT readable from here, so they are matched at download time (pattern),
# and the Hub's answer decides: an unexpected layout stops with the list of files the repository
# holds. Pinned to that card's revision: only its 7-digit id was readable, so the full commit id is
# looked up in the history of main at download time (a prefix missing from it stops the download).
SSSGS_REPO = "CGTuebingen/SSS-GS"
SSSGS_REVISION = "355a987"
SSSGS_MIRROR = (
    "Put the SSS-GS scene archives (from huggingface.co/datasets/CGTuebingen/SSS-GS, folder "
    "synthetic/) into one folder, named <scene>_small.tar (e.g. bunny_small.tar), and run: "
    "olatbench datasets download sssgs --source sssgs-mirror --mirror "
    "file:///path/to/that/folder  (or serve the folder over HTTP and pass its URL)."
)

# --- SSD-GS (ICLR 2026): the authors' copy of all three datasets ----------------------------------
# irisfreesiri/SSD-GS README.md (commit c7025c06486407103644d9bd39421ebffa85cf37, "Dataset
# Preparation"; the link first appeared in b5f4566, where the roadmap marks "Dataset Release" done)
# links one shared OneDrive/SharePoint folder and says to unzip it into data/Real_NRHints/<Scene>,
# data/Synthetic_GS3/<Scene> and data/Synthetic_SSS-GS/<scene>_small. A shared folder has no stable
# per-file URL, so this is a manual source.
SSDGS_DATASET_URL = (
    "https://myvuwac-my.sharepoint.com/:f:/g/personal/zhengjun1_myvuw_ac_nz/"
    "IgADS6vPIEEkTr6Wr64NsT3vAS1dIytv1eDrsh2PW78S-3o?e=F3me3f"
)
SSDGS_FOLDERS = {"nrhints": "Real_NRHints", "gs3": "Synthetic_GS3", "sssgs": "Synthetic_SSS-GS"}


def ssdgs_manual(suite: str) -> str:
    """What to do with the SSD-GS authors' copy of ``suite``'s scenes."""
    folder = SSDGS_FOLDERS[suite]
    return (
        "The SSD-GS authors share their copy of the three datasets "
        "(github.com/irisfreesiri/SSD-GS, README 'Dataset Preparation'): open "
        f"{SSDGS_DATASET_URL} in a browser, download and unzip it, then point olatbench at its "
        f"{folder}/ folder, e.g. olatbench run --suite {suite} --data-root /path/to/data/{folder} "
        "(its scene folder names are the suite's names or aliases; check a scene with olatbench "
        "datasets validate). The archives have no published hashes, so olatbench records none "
        "for them."
    )


def _ssdgs_release(suite: str) -> Source:
    return Source("ssdgs-release", "manual", instructions=ssdgs_manual(suite))


def _nrhints_sources(scene: str) -> list[Source]:
    gs3_name = GS3_NRHINTS_FOLDERS.get(scene, scene)
    return [
        Source(
            "gs3-hf", "hf", files=(f"NRHints/{gs3_name}.zip",), repo=GS3_REPO, revision=GS3_REVISION
        ),
        Source("nrhints-project", "url", files=(f"{scene}.zip",), base_url=NRHINTS_BASE_URL),
        _ssdgs_release("nrhints"),
    ]


def _sssgs_sources(scene: str) -> list[Source]:
    small = f"{scene.lower()}_small"
    return [
        Source(
            "sssgs-hf",
            "hf",
            repo=SSSGS_REPO,
            revision=SSSGS_REVISION,
            pattern=f"synthetic/{small}*",
        ),
        Source("sssgs-mirror", "url", files=(f"{small}.tar",), instructions=SSSGS_MIRROR),
        _ssdgs_release("sssgs"),
    ]


SOURCES: dict[str, dict[str, list[Source]]] = {
    "nrhints": {scene: _nrhints_sources(scene) for scene in SUITES["nrhints"].scenes},
    "gs3": {
        scene: [
            Source(
                "gs3-hf",
                "hf",
                files=(f"Synthetic/{scene}.zip",),
                repo=GS3_REPO,
                revision=GS3_REVISION,
            ),
            _ssdgs_release("gs3"),
        ]
        for scene in SUITES["gs3"].scenes
    },
    "sssgs": {scene: _sssgs_sources(scene) for scene in SUITES["sssgs"].scenes},
}


def sources_for(suite: str, scene: str, source: str | None = None) -> list[Source]:
    """The sources of one scene in the order they are tried, the named one only when ``source`` is
    given.

    Raises `KeyError` listing the choices for an unknown suite, scene or source.
    """
    if suite not in SOURCES:
        raise KeyError(
            f"no download sources for suite '{suite}'; known: {', '.join(sorted(SOURCES))}"
        )
    scenes = SOURCES[suite]
    if scene not in scenes:
        raise KeyError(f"suite '{suite}' has no scene '{scene}'; known: {', '.join(scenes)}")
    candidates = scenes[scene]
    if source is None:
        return candidates
    chosen = [s for s in candidates if s.name == source]
    if not chosen:
        raise KeyError(
            f"scene '{scene}' has no source '{source}'; known: "
            f"{', '.join(s.name for s in candidates)}"
        )
    return chosen
