"""Read what a finished job folder holds for figures and videos: job.json, renders, components,
logs.

Keys read from ``job.json`` (written by `olatbench.bench.execute`): ``id``, ``method``, ``variant``,
``suite``, ``scene``, ``seed``, ``config``, ``scene_path``, ``scene_format``, ``colourspace``,
``resolution``, ``train_split``, ``test_split``. Renders are ``renders/<split>/<stem>.png`` and
components ``components/<split>/<name>/<stem>.png`` (the runner's layout; ``renders/<split>/
components/<name>/<stem>.png`` is read too), where ``stem`` is the frame id made file-safe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.datasets.formats._common import safe_file_stem
from olatbench.datasets.jsontext import parse_json

REQUIRED_JOB_KEYS = (
    "id",
    "method",
    "variant",
    "suite",
    "scene",
    "seed",
    "config",
    "scene_path",
    "scene_format",
    "colourspace",
    "train_split",
    "test_split",
)
COMPONENT_ORDER = ("diffuse", "specular", "sss", "shadow_coarse", "shadow")


class JobFolderError(ValueError):
    """A job folder lacks something a figure or video needs; the message names the file."""


@dataclass(frozen=True)
class JobFolder:
    """One job folder and its job.json."""

    folder: Path
    job: dict[str, Any]

    @classmethod
    def open(cls, folder: str | Path) -> JobFolder:
        folder = Path(folder)
        path = folder / "job.json"
        try:
            job = parse_json(path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise JobFolderError(
                f"{path}: not found; is {folder} a job folder "
                "(<out>/<suite>/<method>/<variant>/<scene>/seed<k>)?"
            ) from None
        # not UTF-8, malformed, nested too deep, an integer too long
        except (OSError, ValueError) as error:
            raise JobFolderError(f"{path}: unreadable ({error})") from None
        if not isinstance(job, dict):
            raise JobFolderError(
                f"{path}: not a job (expected a JSON object, found {type(job).__name__})"
            )
        missing = [key for key in REQUIRED_JOB_KEYS if key not in job]
        if missing:
            raise JobFolderError(f"{path}: missing keys {', '.join(missing)}")
        return cls(folder, job)

    @property
    def label(self) -> str:
        job = self.job
        return f"{job['method']}/{job['variant']}/{job['scene']}/seed{job['seed']}"

    @property
    def resolution(self) -> tuple[int, int] | None:
        value = self.job.get("resolution")
        return (int(value[0]), int(value[1])) if value else None

    def load_scene(self):
        """The job's scene through `olatbench.datasets.load_scene` (a `JobFolderError` if the data
        moved)."""
        from olatbench.datasets import load_scene

        path = Path(self.job["scene_path"])
        if not path.exists():
            raise JobFolderError(
                f"{self.folder / 'job.json'}: scene_path {path} does not exist (data moved?)"
            )
        return load_scene(path, format=self.job["scene_format"])

    def render_path(self, split: str, frame_id: str) -> Path:
        return self.folder / "renders" / split / f"{safe_file_stem(frame_id)}.png"

    def component_path(self, split: str, name: str, frame_id: str) -> Path | None:
        """The saved component image, or None when the job did not save it."""
        stem = f"{safe_file_stem(frame_id)}.png"
        for path in (
            self.folder / "components" / split / name / stem,
            self.folder / "renders" / split / "components" / name / stem,
        ):
            if path.is_file():
                return path
        return None

    def components(self, split: str, frame_id: str) -> dict[str, Path]:
        """Saved components of one frame in the paper's order (diffuse, specular, SSS, shadows),
        then others."""
        names = set()
        for root in (
            self.folder / "components" / split,
            self.folder / "renders" / split / "components",
        ):
            if root.is_dir():
                names.update(child.name for child in root.iterdir() if child.is_dir())
        ordered = [n for n in COMPONENT_ORDER if n in names] + sorted(names - set(COMPONENT_ORDER))
        found = {name: self.component_path(split, name, frame_id) for name in ordered}
        return {name: path for name, path in found.items() if path is not None}

    def train_log(self) -> list[dict[str, float]]:
        """The entries of ``train_log.jsonl`` (step, loss, psnr, ...); unreadable lines are
        reported."""
        path = self.folder / "train_log.jsonl"
        if not path.is_file():
            raise JobFolderError(f"{path}: not found (the job has not logged training yet)")
        entries = []
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
            if not line.strip():
                continue
            try:
                entry = parse_json(line)
            except ValueError as error:
                raise JobFolderError(f"{path}:{number}: {error}") from None
            if not isinstance(entry, dict) or "step" not in entry:
                raise JobFolderError(f"{path}:{number}: expected an object with 'step'")
            entries.append(
                {
                    k: (math.nan if v is None else float(v))
                    for k, v in entry.items()
                    if isinstance(v, (int, float)) or v is None
                }
            )
        return entries


def read_png(path: str | Path) -> np.ndarray:
    """An 8-bit PNG as float32 (H, W, 3) in [0, 1] (grey maps repeated to 3 channels, alpha
    dropped)."""
    from olatbench.datasets.images import read_image

    pixels = read_image(path)
    if pixels.ndim == 2:
        pixels = pixels[..., None]
    if pixels.shape[2] == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    return np.ascontiguousarray(pixels[..., :3], dtype=np.float32)
