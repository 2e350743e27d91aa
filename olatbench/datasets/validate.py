"""Check a dataset tree frame by frame and report every problem, not just the first one.

Checks: the transforms files parse; every frame has its keys with finite values and a ``file_path``
inside the root; every image exists, decodes, has the camera's resolution, 1/3/4 channels and finite
pixels; camera rotations are orthonormal; lights are not inside the camera (distance to the camera
centre > ``near``, or > 0 when ``near`` is unknown). Warnings: several resolutions in one scene;
SSS-GS principal points off the centre (the official projection ignores them).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import detect_format, format_module
from olatbench.datasets.images import check_image_file
from olatbench.datasets.records import Frame, Scene


@dataclass(frozen=True)
class Issue:
    """One problem: ``severity`` is ``error`` or ``warning``."""

    severity: str
    message: str
    path: str | None = None
    frame: str | None = None
    key: str | None = None

    @classmethod
    def from_error(cls, error: DatasetError, severity: str = "error") -> Issue:
        return cls(
            severity,
            error.message,
            None if error.path is None else str(error.path),
            None if error.frame is None else str(error.frame),
            error.key,
        )

    def __str__(self) -> str:
        return str(DatasetError(self.message, path=self.path, frame=self.frame, key=self.key))


@dataclass
class ValidationReport:
    """The outcome for one scene folder."""

    root: str
    format: str | None = None
    scene: str | None = None
    frames: dict[str, int] = field(default_factory=dict)  # split -> frames checked
    issues: list[Issue] = field(default_factory=list)

    @property
    def errors(self) -> list[Issue]:
        return [issue for issue in self.issues if issue.severity == "error"]

    @property
    def ok(self) -> bool:
        return not self.errors

    def to_dict(self) -> dict[str, Any]:
        return {
            "root": self.root,
            "format": self.format,
            "scene": self.scene,
            "frames": self.frames,
            "ok": self.ok,
            "errors": len(self.errors),
            "warnings": len(self.issues) - len(self.errors),
            "issues": [asdict(issue) for issue in self.issues],
        }


def check_frame(frame: Frame, decode: bool = True) -> list[Issue]:
    """The problems of one frame (image, camera, light)."""
    issues: list[Issue] = []
    where = {
        "path": None if frame.image_path is None else str(frame.image_path),
        "frame": frame.frame_id,
    }
    if frame.image_path is not None:
        try:
            check_image_file(frame.image_path)
            if decode:
                frame.load(background=None)
        except DatasetError as error:
            issues.append(
                Issue.from_error(
                    DatasetError(
                        error.message, path=error.path, frame=frame.frame_id, key=error.key
                    )
                )
            )
    rotation = frame.camera.c2w[:3, :3]
    if not np.allclose(rotation.T @ rotation, np.eye(3), atol=1e-3):
        issues.append(
            Issue("error", "camera rotation is not orthonormal", key="transform_matrix", **where)
        )
    distance = float(np.linalg.norm(frame.light.position - frame.camera.position))
    near = frame.camera.near or 0.0
    if distance <= near or distance == 0.0:
        issues.append(
            Issue(
                "error",
                f"light is inside the camera: {distance:.4g} from its centre (near = {near:.4g})",
                key="pl_pos",
                **where,
            )
        )
    return issues


def validate_scene(scene: Scene, decode: bool = True, progress: bool = False) -> ValidationReport:
    """Check every frame of an already-read scene."""
    from olatbench.progress import progress_bar

    report = ValidationReport(
        root=str(scene.root),
        format=scene.format,
        scene=scene.name,
        frames={split: len(frames) for split, frames in scene.frames.items()},
    )
    frames = list(scene)
    for frame in progress_bar(
        frames, desc=f"validate {scene.name}", disable=not progress, unit="frame"
    ):
        report.issues.extend(check_frame(frame, decode))
    if scene.format == "sssgs":
        off_centre = [
            f
            for f in frames
            if max(abs(f.camera.cx - f.camera.width / 2), abs(f.camera.cy - f.camera.height / 2))
            > 0.5
        ]
        if off_centre:
            report.issues.append(
                Issue(
                    "warning",
                    f"{len(off_centre)} records have a principal point more than 0.5 px "
                    "off the image centre; the official SSS-GS projection ignores cx, cy",
                    path=str(scene.root),
                    frame=off_centre[0].frame_id,
                    key="cx",
                )
            )
    sizes = Counter((f.camera.width, f.camera.height) for f in frames if f.image_path is not None)
    if len(sizes) > 1:
        report.issues.append(
            Issue(
                "warning",
                "several resolutions: "
                + ", ".join(f"{w}×{h} ({n} frames)" for (w, h), n in sizes.most_common()),
                path=str(scene.root),
            )
        )
    return report


def validate_folder(
    root: str | Path, format: str | None = None, decode: bool = True, progress: bool = False
) -> ValidationReport:
    """Read a scene folder leniently (bad frames become issues) and check every frame."""
    root = Path(root)
    report = ValidationReport(root=str(root))
    try:
        report.format = format or detect_format(root)
        errors: list[DatasetError] = []
        scene = format_module(report.format).read_scene(root, errors=errors)
    except DatasetError as error:
        report.issues.append(Issue.from_error(error))
        return report
    checked = validate_scene(scene, decode, progress)
    checked.issues[:0] = [Issue.from_error(error) for error in errors]
    checked.format = report.format
    return checked
