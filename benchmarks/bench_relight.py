"""A trained job relit under lightings against Mitsuba's ground truth of its recipe
(docs/relighting.md): PSNR (sRGB) and mean brightness ratio over a few test views, for each distance
factor at which directional lights are probed.

    python benchmarks/bench_relight.py JOB --recipe diffuse_shadow --views 5 --factors 1,2,1000
    --samples 32

The job must have been trained on the recipe's scene (e.g. the mini suite's, whose scenes are the
built-in recipes at their defaults), so that its test frames are the recipe's test cameras. The
ground truth is rendered once per lighting into ``--cache``
(`olatbench.datasets.synth.lit.render_lit`) and reused. A check of the relighting choices on one
model, not a benchmark protocol.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from olatbench.bench.relight import restore_relighter
from olatbench.datasets import colour, load_scene
from olatbench.datasets.images import read_image
from olatbench.datasets.lighting import lighting_from_dict
from olatbench.datasets.synth.lit import SCENE_UP, render_lit
from olatbench.datasets.synth.recipe import get_recipe


def lightings(centre: np.ndarray, samples: int) -> dict[str, dict]:
    """The lightings compared (the recipes' vertical is +z; 3.2 is the mini rig's irradiance, 80 /
    5²)."""
    e, a = np.radians(40.0), np.radians(135.0)
    towards = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    return {
        "directional": {
            "lights": [{"type": "directional", "direction": towards.tolist(), "irradiance": 3.2}]
        },
        "point": {
            "lights": [
                {"type": "point", "position": (centre + 5.0 * towards).tolist(), "intensity": 80}
            ]
        },
        "two points": {
            "lights": [
                {
                    "type": "point",
                    "position": (centre + np.array([3.0, -3.0, 3.5])).tolist(),
                    "intensity": 60,
                },
                {
                    "type": "point",
                    "position": (centre + np.array([-3.5, 1.0, 2.5])).tolist(),
                    "intensity": [50, 40, 30],
                },
            ]
        },
        "studio": {
            "samples": samples,
            "lights": [{"type": "envmap", "map": "studio", "up": [0, 0, 1]}],
        },
        "sky": {"samples": samples, "lights": [{"type": "envmap", "map": "sky", "up": [0, 0, 1]}]},
    }


def shown(linear: np.ndarray) -> np.ndarray:
    return np.clip(colour.convert_colourspace(linear, "linear", "srgb"), 0.0, 1.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("job", type=Path)
    parser.add_argument("--recipe", required=True)
    parser.add_argument("--views", type=int, default=5)
    parser.add_argument("--factors", default="1,1000")
    parser.add_argument("--samples", type=int, default=32)
    parser.add_argument("--only", help="comma-separated lighting names (default: all)")
    parser.add_argument("--cache", type=Path, default=Path("bench_relight_gt"))
    args = parser.parse_args()
    relighter, job = restore_relighter(args.job)
    test = load_scene(job.scene_path, format=job.scene_format).split(job.test_split)[: args.views]
    recipe = get_recipe(args.recipe)
    for name, data in lightings(relighter.reference.centre, args.samples).items():
        if args.only and name not in args.only.split(","):
            continue
        lighting = lighting_from_dict(data)
        folder = args.cache / args.recipe / name.replace(" ", "_")
        if not (folder / "lit.json").exists():
            render_lit(recipe, lighting, folder, progress=False)
        sampled = lighting.sample(SCENE_UP)
        # points: as they are
        factors = [float(f) for f in args.factors.split(",")] if sampled.directions else [1.0]
        for factor in factors:
            relighter.distant_factor = factor
            psnrs, ratios = [], []
            for frame in test:
                truth = read_image(folder / f"{frame.frame_id}.exr")
                truth = truth[..., :3] * truth[..., 3:4]  # on the job's black background
                relit = relighter.linear(frame.camera, sampled)
                psnrs.append(-10.0 * np.log10(np.mean((shown(relit) - shown(truth)) ** 2)))
                ratios.append(relit.mean() / truth.mean())
            print(
                f"{name:12s} × {factor:g}: PSNR {np.mean(psnrs):.2f} dB, brightness ratio "
                f"{np.mean(ratios):.3f} ({len(test)} views, {len(sampled)} lights)",
                flush=True,
            )


if __name__ == "__main__":
    main()
