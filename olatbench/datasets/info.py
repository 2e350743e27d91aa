"""Summaries of scene folders: format, splits, resolutions, colour, lights
(``olatbench datasets info``)."""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.datasets.errors import DatasetError
from olatbench.datasets.formats import is_scene_folder
from olatbench.datasets.novel_lights import condition_names
from olatbench.datasets.records import Scene


def find_scene_folders(path: str | Path) -> list[Path]:
    """``path`` itself when it holds a scene, else its sub-folders that do (sorted)."""
    path = Path(path)
    if not path.is_dir():
        raise DatasetError("folder not found", path=path)
    if is_scene_folder(path):
        return [path]
    scenes = sorted(child for child in path.iterdir() if is_scene_folder(child))
    if not scenes:
        raise DatasetError(
            "neither a scene folder (transforms_*.json) nor a folder of scene folders", path=path
        )
    return scenes


def _range(values: np.ndarray) -> list[float] | None:
    return [float(values.min()), float(values.max())] if values.size else None


def scene_summary(scene: Scene) -> dict[str, Any]:
    """A JSON-ready summary of a scene."""
    frames = list(scene)
    lights = np.array([f.light.position for f in frames]).reshape(-1, 3)
    cameras = np.array([f.camera.position for f in frames]).reshape(-1, 3)
    sizes = Counter(f"{f.camera.width}x{f.camera.height}" for f in frames)
    distinct_lights = len({tuple(np.round(p, 6)) for p in lights})
    return {
        "scene": scene.name,
        "format": scene.format,
        "root": str(scene.root),
        "splits": {split: len(split_frames) for split, split_frames in scene.frames.items()},
        "images": sum(f.image_path is not None for f in frames),
        # absolute img_path (GS³/SSD-GS Scene.save): images read from outside the folder
        "images_outside_folder": sum("absolute_img_path" in f.extras for f in frames),
        "refined_poses": sum("R_opt" in f.extras for f in frames),
        "resolution": dict(sizes),
        "colourspace": sorted({f.colourspace for f in frames}),
        "alpha": sorted({f.alpha_mode for f in frames}),
        "background": np.asarray(scene.background, dtype=float).tolist(),
        "novel_lights": condition_names(scene.root),
        "lights": {
            "distinct_positions": distinct_lights,
            "distance_to_origin": _range(np.linalg.norm(lights, axis=1)),
            "distance_to_camera": _range(np.linalg.norm(lights - cameras, axis=1)),
            "intensity_known": bool(frames) and all(f.light.intensity_known for f in frames),
        },
        "camera_distance_to_origin": _range(np.linalg.norm(cameras, axis=1)),
        "metadata": {k: v for k, v in scene.metadata.items() if k != "files"},
    }


def format_summary(summary: dict[str, Any]) -> str:
    """Human-readable lines for one `scene_summary`."""
    lights = summary["lights"]

    def span(values: list[float] | None) -> str:
        return "—" if values is None else f"{values[0]:.3g} – {values[1]:.3g}"

    lines = [
        f"{summary['scene']}  ({summary['format']}, {summary['root']})",
        "  splits:      " + ", ".join(f"{split} {n}" for split, n in summary["splits"].items()),
        "  resolution:  " + ", ".join(f"{size} ({n})" for size, n in summary["resolution"].items()),
        f"  colour:      {'/'.join(summary['colourspace'])}, {'/'.join(summary['alpha'])} alpha, "
        f"background {summary['background']}",
        f"  lights:      {lights['distinct_positions']} distinct positions; distance to origin "
        f"{span(lights['distance_to_origin'])}, to camera {span(lights['distance_to_camera'])}; "
        f"intensity {'known' if lights['intensity_known'] else 'unknown (1)'}",
        f"  cameras:     distance to origin {span(summary['camera_distance_to_origin'])}",
    ]
    if summary["novel_lights"]:
        lines.append(
            f"  novel lights: {', '.join(summary['novel_lights'])} (ground truth of the test views "
            "under these lightings, novel_lights/)"
        )
    if summary["refined_poses"]:
        lines.append(
            f"  poses:       {summary['refined_poses']} frame(s) posed by their refined R_opt/T_opt"
        )
    if summary["images_outside_folder"]:
        lines.append(
            f"  images:      {summary['images_outside_folder']} read from outside the folder "
            "(absolute img_path, as GS³/SSD-GS Scene.save writes them)"
        )
    extra = {k: v for k, v in summary["metadata"].items() if k != "folder"}
    if extra:
        lines.append("  notes:       " + ", ".join(f"{k}={v}" for k, v in extra.items()))
    return "\n".join(lines)
