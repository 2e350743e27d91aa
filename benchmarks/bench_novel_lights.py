"""How well OLAT-trained models carry over to novel illumination (docs/relighting.md, issue #57 item
4): finished mini jobs copied and scored under the novel-light ground truth
(`olatbench.bench.novel_lights.add_novel_lights`), and the figure of ground truth against renders
per condition.

    python benchmarks/bench_novel_lights.py truth --out TRUTH --views 3  # no packaged truth
    python benchmarks/bench_novel_lights.py score --runs TRAINED/mini --out RUNS/mini \\
        --truth TRUTH --views 3 --samples 16
    olatbench report RUNS --suite mini --format markdown                      # the tables
    python benchmarks/bench_novel_lights.py table --runs RUNS/mini   # docs/relighting.md
    python benchmarks/bench_novel_lights.py figure --runs RUNS/mini --truth TRUTH \\
        --scene aniso_metal -o docs/img/novel_lights_aniso_metal.png

``truth`` renders, with Mitsuba, the first ``--views`` test cameras of each mini scene under the
lighting files of ``benchmarks/novel_lights/`` into ``TRUTH/<scene>/novel_lights/<condition>/`` (the
layout of `olatbench.datasets.novel_lights`, as `olatbench.datasets.synth.lit.render_lit` renders
them: same cameras, seeds and samples per pixel). ``score`` copies each finished job below
``--runs`` (method/variant/scene/seed) to ``--out`` (the source is never written) and adds its
scores; ``--truth`` defaults to each job's scene folder (the mini suite's packaged ground truth,
installed on first use). Since the packaged reader
(`olatbench.datasets.novel_lights.load_condition`) checks a condition against its scene's whole test
split, a ``truth`` folder of a few views is no longer accepted by ``score --truth``:
docs/relighting.md's measurement was made with it before that reader was merged.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import time
from pathlib import Path

import numpy as np

from olatbench.atomic import write_json
from olatbench.bench.novel_lights import NovelLightsOptions, add_novel_lights, ground_truth_image
from olatbench.bench.results import read_results
from olatbench.datasets import colour, load_scene
from olatbench.datasets.images import read_image
from olatbench.datasets.lighting import lighting_to_dict, read_lighting
from olatbench.datasets.novel_lights import CONDITIONS, condition_names, load_condition

LIGHTINGS = Path(__file__).resolve().parent / "novel_lights"


def render_truth(out: Path, views: int, scenes: list[str], spp_factor: int = 1) -> None:
    """The mini scenes' first ``views`` test cameras under each lighting of `LIGHTINGS`
    (module docstring), at ``spp_factor`` times the recipe's samples per pixel."""
    from olatbench.datasets.images import write_image
    from olatbench.datasets.synth.generate import frame_seed
    from olatbench.datasets.synth.lit import LitRenderer
    from olatbench.datasets.synth.mini import mini_recipes
    from olatbench.datasets.synth.rigs import make_rig

    for scene in scenes:
        recipe = mini_recipes()[scene]
        recipe = dataclasses.replace(recipe, spp=recipe.spp * spp_factor)
        for name in CONDITIONS:
            folder = out / scene / "novel_lights" / name
            if (folder / "lit.json").is_file():
                continue
            lighting = read_lighting(LIGHTINGS / f"{name}.json")
            clock = time.perf_counter()
            renderer = LitRenderer(recipe, lighting)
            rig = make_rig(recipe, renderer.mesh.bounding_sphere()[0])
            train, test = rig.frames.get("train", []), rig.frames.get("test", [])
            folder.mkdir(parents=True, exist_ok=True)
            frames = {}
            for number, (camera, _) in enumerate(test[:views]):
                frame_id, seed = f"r_{number:04d}", frame_seed(recipe, len(train) + number)
                write_image(
                    folder / f"{frame_id}.exr", renderer.render(camera, seed), bit_depth="float"
                )
                frames[frame_id] = {"c2w": np.asarray(camera.c2w).tolist(), "seed": seed}
            write_json(folder / "lighting.json", lighting_to_dict(lighting))
            write_json(
                folder / "lit.json",
                {
                    "recipe": recipe.to_dict(),
                    "split": "test",
                    "frames": frames,
                    "note": f"the first {views} test cameras only (benchmarks/"
                    "bench_novel_lights.py)",
                },
            )
            print(
                f"{scene} {name}: {len(frames)} views in {time.perf_counter() - clock:.0f} s",
                flush=True,
            )


def score(
    runs: Path,
    out: Path,
    truth: Path | None,
    options: NovelLightsOptions,
    methods: list[str],
    variant: str = "default",
) -> None:
    """Copy and score every finished job of ``methods`` (their ``variant``) below ``runs``
    (module docstring)."""
    for source in sorted(runs.glob(f"*/{variant}/*/seed*")):
        method, variant, scene, seed = source.relative_to(runs).parts
        if method not in methods or not (source / "DONE").is_file():
            continue
        target = out / method / variant / scene / seed
        if target.is_dir() and read_results(target / "results.json").get("novel_lights"):
            continue
        shutil.rmtree(target, ignore_errors=True)
        shutil.copytree(source, target, ignore=shutil.ignore_patterns("renders", "components"))
        clock = time.perf_counter()
        block = add_novel_lights(target, options, truth=None if truth is None else truth / scene)
        shown = ", ".join(
            f"{name} {c['mean']['psnr']:.2f}/{c['mean']['psnr_si']:.2f}"
            for name, c in block["conditions"].items()
        )
        print(
            f"{method}/{scene}/{seed}: {shown} dB (PSNR/scale-inv.) in "
            f"{time.perf_counter() - clock:.0f} s",
            flush=True,
        )


def figure(
    runs: Path,
    truth: Path | None,
    scene: str,
    seed: str,
    frame_id: str | None,
    output: Path,
    variant: str = "default",
) -> None:
    """Rows: the conditions; columns: the ground truth, then each method's render
    (``variant``, seed ``seed``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    jobs = sorted(
        path
        for path in runs.glob(f"*/{variant}/{scene}/{seed}")
        if (path / "results.json").is_file()
    )
    job = read_results(jobs[0] / "results.json")
    scene_path = Path(json.loads((jobs[0] / "job.json").read_text())["scene_path"])
    truth_folder = truth / scene if truth is not None else scene_path
    frames = {frame.frame_id: frame for frame in load_scene(scene_path).split("test")}
    names = condition_names(truth_folder)
    chosen = frame_id or sorted(load_condition(truth_folder, names[0]).frames)[0]
    fig, axes = plt.subplots(
        len(names), 1 + len(jobs), figsize=(1.6 * (1 + len(jobs)), 1.6 * len(names)), squeeze=False
    )
    for row, name in enumerate(names):
        condition = load_condition(truth_folder, name)
        gt, _ = ground_truth_image(condition.frames[chosen], frames[chosen], "linear", None)
        images = [("ground truth", np.clip(colour.convert_colourspace(gt, "linear", "srgb"), 0, 1))]
        for path in jobs:
            scores = read_results(path / "results.json")["novel_lights"]["conditions"][name][
                "per_image"
            ][chosen]
            label = f"{path.parts[-4]} {scores['psnr']:.1f} / {scores['psnr_si']:.1f} dB"
            images.append(
                (label, read_image(path / "renders" / "novel_lights" / name / f"{chosen}.png"))
            )
        for column, (label, image) in enumerate(images):
            axis = axes[row, column]
            axis.imshow(image)
            axis.set_xticks([])
            axis.set_yticks([])
            axis.set_title(label, fontsize=6)
            if column == 0:
                axis.set_ylabel(name, fontsize=7)
    fig.suptitle(
        f"{scene}, {chosen}, {seed}\nPSNR (image) / scale-inv. PSNR (object), dB\n"
        f"{job['novel_lights']['protocol']['id']}",
        fontsize=7,
    )
    fig.tight_layout()
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=110)
    print(f"wrote {output}")


def summary(runs: Path, scenes: list[str] | None) -> str:
    """Markdown: per method (rows) the OLAT test PSNR and, per condition, PSNR (image) and PSNR
    (object) → scale- invariant PSNR, each the mean over ``scenes`` per seed, then mean ± std
    (ddof 1) over the seeds that have every scene; a second table per scene."""
    import pandas as pd

    from olatbench.reports.collect import collect

    frame = collect(runs)
    frame = frame[
        (frame["status"] == "done") & frame["metric"].isin(("psnr", "psnr_object", "psnr_si"))
    ]
    same_views = []  # the OLAT test PSNR over the very test frames scored under the conditions
    for path in sorted(runs.rglob("results.json")):
        results = read_results(path)
        if results["status"] == "done" and results.get("novel_lights"):
            frames = {
                fid
                for condition in results["novel_lights"]["conditions"].values()
                for fid in condition["per_image"]
            }
            per_image = results["metrics"]["test"]["per_image"]
            row = frame[
                (frame["path"] == str(path))
                & (frame["split"] == "test")
                & (frame["metric"] == "psnr")
            ]
            same_views.append(
                {
                    **row.iloc[0].to_dict(),
                    "split": "test_views",
                    "value": float(np.mean([per_image[fid]["psnr"] for fid in sorted(frames)])),
                }
            )
    frame = pd.concat([frame, pd.DataFrame(same_views)], ignore_index=True)
    scenes = scenes or sorted(set(frame["scene"]))
    splits = [
        "test",
        "test_views",
        *[f"novel:{name}" for name in CONDITIONS if f"novel:{name}" in set(frame["split"])],
        "novel",
    ]

    def cell(rows: pd.DataFrame, split: str, metric: str, over: list[str]) -> str:
        chosen = rows[
            (rows["split"] == split) & (rows["metric"] == metric) & rows["scene"].isin(over)
        ]
        per_seed = chosen.groupby("seed")["value"].agg(["mean", "count"])
        values = per_seed[per_seed["count"] == len(over)]["mean"]
        if values.empty:
            return "—"
        return (
            f"{values.mean():.2f} ± {values.std(ddof=1):.2f}"
            if len(values) > 1
            else f"{values.mean():.2f}"
        )

    titles = {
        "test": "OLAT test (all views)",
        "test_views": "OLAT test (these views)",
        "novel": "mean of conditions",
    }
    lines = []
    for title, over in [
        ("mean over " + ", ".join(scenes), scenes),
        *[(scene, [scene]) for scene in scenes],
    ]:
        lines += [
            f"**{title}** (PSNR of the image; object PSNR → scale-invariant PSNR; dB, mean ± std "
            "over seeds)",
            "",
            "| method | seeds | "
            + " | ".join(titles.get(s, s.removeprefix("novel:")) for s in splits)
            + " |",
            "|---" * (len(splits) + 2) + "|",
        ]
        for (method, variant), rows in frame.groupby(["method", "variant"], sort=True):
            method = method if variant == "default" else f"{method} ({variant} preset)"
            seeds = rows[rows["split"] == "novel"]["seed"].nunique()
            cells = [cell(rows, "test", "psnr", over), cell(rows, "test_views", "psnr", over)]
            cells += [
                f"{cell(rows, s, 'psnr', over)}<br>{cell(rows, s, 'psnr_object', over)} → "
                f"{cell(rows, s, 'psnr_si', over)}"
                for s in splits[2:]
            ]
            lines.append(f"| {method} | {seeds} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    commands = parser.add_subparsers(dest="command", required=True)
    truth = commands.add_parser("truth")
    truth.add_argument("--out", type=Path, required=True)
    truth.add_argument("--views", type=int, default=3)
    truth.add_argument("--scenes", default="diffuse_shadow,aniso_metal,translucent")
    truth.add_argument(
        "--spp-factor", type=int, default=1, help="times the recipe's samples per pixel"
    )
    scoring = commands.add_parser("score")
    scoring.add_argument("--runs", type=Path, required=True)
    scoring.add_argument("--out", type=Path, required=True)
    scoring.add_argument("--truth", type=Path)
    scoring.add_argument("--views", type=int)
    scoring.add_argument("--samples", type=int)
    scoring.add_argument("--methods", default="ssdgs,gs3,3dgs")
    scoring.add_argument("--variant", default="default")
    drawing = commands.add_parser("figure")
    drawing.add_argument("--runs", type=Path, required=True)
    drawing.add_argument("--truth", type=Path)
    drawing.add_argument("--scene", default="diffuse_shadow")
    drawing.add_argument("--seed", default="seed0")
    drawing.add_argument("--frame")
    drawing.add_argument("--variant", default="default")
    drawing.add_argument("-o", "--output", type=Path, required=True)
    table = commands.add_parser("table")
    table.add_argument("--runs", type=Path, required=True)
    table.add_argument("--scenes")
    args = parser.parse_args()
    if args.command == "truth":
        render_truth(args.out, args.views, args.scenes.split(","), args.spp_factor)
    elif args.command == "score":
        score(
            args.runs,
            args.out,
            args.truth,
            NovelLightsOptions(args.samples, args.views),
            args.methods.split(","),
            args.variant,
        )
    elif args.command == "table":
        print(summary(args.runs, args.scenes.split(",") if args.scenes else None))
    else:
        figure(args.runs, args.truth, args.scene, args.seed, args.frame, args.output, args.variant)


if __name__ == "__main__":
    main()
