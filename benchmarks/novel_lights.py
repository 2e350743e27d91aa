"""The mini suite's ground truth under new illumination (docs/relighting.md): a figure, its
exposure, its noise.

    python benchmarks/novel_lights.py figure -o docs/img/novel_lights.png --view r_0004
    python benchmarks/novel_lights.py noise --condition studio --views 5
    python benchmarks/novel_lights.py exposure

``figure``: one test view per scene (rows) under the OLAT test light and each condition (columns),
sRGB on the mini suite's black background, a PNG grid. ``exposure``: per scene and condition, the
mean linear value of the covered pixels (alpha > 0.5) over the 20 test views relative to the OLAT
test images', and the share of covered pixels with a channel ≥ 1 (clipped on display). ``noise``:
each scene's packaged renders of one condition against the same views rendered again at 4× their
samples per pixel with other sampler seeds (`olatbench.datasets.synth.lit`): the PSNR (sRGB in [0,
1], premultiplied on black) over whole images and over covered pixels, and the CPU time. The MSE of
two independent renders at N and 4N samples is 1.25 times that of the N-sample one against the
noise-free image, so the packaged ground truth's own noise floor is about 1 dB above the PSNR
printed. All read the installed suite (``--root``, default the cache: installed from the package
when missing).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import cv2
import numpy as np

from olatbench.datasets import colour, load_scene
from olatbench.datasets.images import read_image, write_image
from olatbench.datasets.novel_lights import CONDITIONS, SPP, condition_lighting, load_condition
from olatbench.datasets.synth.mini import MINI_SCENES, MINI_VARIANT, ensure_mini_suite, mini_recipes

# the 4× renders' sampler seeds: the packaged frame's seed plus this (independent samples)
SEED_OFFSET = 7_919


def display(rgba: np.ndarray) -> np.ndarray:
    """(H, W, 3) sRGB in [0, 1] of linear RGB + straight alpha over black (as the mini suite's PNGs
    are)."""
    return np.clip(
        colour.linear_to_srgb(np.clip(colour.premultiply(rgba[..., :3], rgba[..., 3]), 0.0, None)),
        0.0,
        1.0,
    )


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    return float(10.0 * np.log10(1.0 / np.mean((a - b) ** 2)))


def figure(root: Path, out: Path, view: str, scale: int) -> None:
    """The grid: rows the mini scenes, columns the OLAT test image and each condition."""
    header, label_width = 22, 118
    rows = []
    for name in MINI_SCENES:
        scene = root / name
        frame = next(frame for frame in load_scene(scene).split("test") if frame.frame_id == view)
        tiles = [np.asarray(frame.load().rgb, dtype=np.float32)[..., :3]]
        tiles += [
            display(read_image(load_condition(scene, condition).frames[view]))
            for condition in CONDITIONS
        ]
        tiles = [
            np.rint(255 * np.repeat(np.repeat(tile, scale, axis=0), scale, axis=1)).astype(np.uint8)
            for tile in tiles
        ]
        row = np.concatenate(
            [np.full((tiles[0].shape[0], label_width, 3), 255, np.uint8), *tiles], axis=1
        )
        cv2.putText(
            row,
            name,
            (4, row.shape[0] // 2),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.42,
            (0, 0, 0),
            1,
            cv2.LINE_AA,
        )
        rows.append(row)
    top = np.full((header, rows[0].shape[1], 3), 255, np.uint8)
    width = (rows[0].shape[1] - label_width) // (len(CONDITIONS) + 1)
    for index, title in enumerate(("OLAT test light", *CONDITIONS)):
        cv2.putText(
            top,
            title,
            (label_width + index * width + 4, 15),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.42,
            (0, 0, 0),
            1,
            cv2.LINE_AA,
        )
    write_image(out, np.concatenate([top, *rows], axis=0) / 255.0, "uint8")
    print(f"wrote {out}")


def exposure(root: Path) -> None:
    """Print the conditions' brightness against the OLAT test images' and their clipped share
    (module docstring)."""
    print(f"{'scene':15s} {'OLAT mean':>9s}  " + "  ".join(f"{name:>17s}" for name in CONDITIONS))
    for name in MINI_SCENES:
        olat = []
        for frame in load_scene(root / name).split("test"):
            pixels = read_image(frame.image_path)
            olat.append(colour.srgb_to_linear(pixels[..., :3])[pixels[..., 3] > 0.5].mean())
        cells = []
        for condition in CONDITIONS:
            means, clipped = [], []
            for path in load_condition(root / name, condition).frames.values():
                image = read_image(path)
                covered = image[..., :3][image[..., 3] > 0.5]
                means.append(covered.mean())
                clipped.append(np.mean(covered.max(axis=-1) >= 1.0))
            cells.append(
                f"×{np.mean(means) / np.mean(olat):.2f} ({100 * np.mean(clipped):.1f} % ≥ 1)"
            )
        print(f"{name:15s} {np.mean(olat):9.3f}  " + "  ".join(f"{cell:>17s}" for cell in cells))


def noise(root: Path, condition: str, views: int, scenes: list[str]) -> None:
    """Print each scene's PSNR between the packaged renders of ``condition`` and renders at 4× their
    samples."""
    from olatbench.datasets.synth.backend import pinned_variant
    from olatbench.datasets.synth.generate import frame_seed
    from olatbench.datasets.synth.lit import LitRenderer
    from olatbench.datasets.synth.rigs import make_rig

    print(
        f"{condition}: the packaged renders ({SPP} spp) against {4 * SPP} spp, {views} test views "
        "per scene"
    )
    for name in scenes:
        recipe = mini_recipes()[name].with_overrides(spp=4 * SPP)
        packaged = load_condition(root / name, condition).frames
        start = time.process_time()
        with pinned_variant(MINI_VARIANT):
            renderer = LitRenderer(recipe, condition_lighting(condition))
            rig = make_rig(recipe, renderer.mesh.bounding_sphere()[0])
            train, test = rig.frames["train"], rig.frames["test"]
            whole, covered = [], []
            for number, frame_id in enumerate(list(packaged)[:views]):
                ours = renderer.render(
                    test[number][0], frame_seed(recipe, len(train) + number) + SEED_OFFSET
                )
                theirs = read_image(packaged[frame_id])
                a, b = display(ours), display(theirs)
                mask = theirs[..., 3] > 0.5
                whole.append(psnr(a, b))
                covered.append(psnr(a[mask], b[mask]))
        print(
            f"  {name:15s} PSNR {np.mean(whole):.1f} dB (views {min(whole):.1f} … "
            f"{max(whole):.1f}); covered pixels {np.mean(covered):.1f} dB; CPU "
            f"{(time.process_time() - start) / views:.1f} s per {4 * SPP}-spp view"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("what", choices=["figure", "noise", "exposure"])
    parser.add_argument(
        "--root", type=Path, default=None, help="the mini suite (default: installed in the cache)"
    )
    parser.add_argument("-o", "--out", type=Path, default=Path("docs/img/novel_lights.png"))
    parser.add_argument("--view", default="r_0004", help="figure: the test frame shown")
    parser.add_argument("--scale", type=int, default=2, help="figure: pixels per image pixel")
    parser.add_argument("--condition", default="studio", choices=CONDITIONS)
    parser.add_argument("--views", type=int, default=5, help="noise: test views per scene")
    parser.add_argument(
        "--scenes", default=",".join(MINI_SCENES), help="noise: the scenes, comma-separated"
    )
    args = parser.parse_args()
    root = args.root or ensure_mini_suite(progress=False)
    if args.what == "figure":
        figure(root, args.out, args.view, args.scale)
    elif args.what == "exposure":
        exposure(root)
    else:
        noise(root, args.condition, args.views, args.scenes.split(","))


if __name__ == "__main__":
    main()
