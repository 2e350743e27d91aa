"""Frames/s of `Frame.load` (decode + compositing + colour conversion) vs a bare OpenImageIO decode
loop.

Writes a small 512² GS³ tree (half EXR) and NRHints tree (8-bit PNG) to a temporary folder, then
times, in the same run and on the same files:

Rates are frames per CPU-second (the machine may be shared).

* ``bare``: ``ImageInput.open`` + ``read_image(float)`` per file (the floor any loader pays), result
  dropped;
* ``load``: ``Frame.load(colourspace=<the suite's space>)`` — what a method receives (GS³ → gamma
  2.2 on white, NRHints → sRGB on black), result dropped too: both loops stream, so neither pays for
  fresh memory the other reuses;
* ``convert``: ``write_scene`` of the same frames to the other format, per frame
  (decode + re-encode).

Target: ``load`` overhead ≤ 25 % over ``bare``. Last line: ``BENCH datasets ...`` key=value pairs.

    python benchmarks/bench_datasets.py [--frames 12] [--size 512] [--repeats 3]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from datasets_trees import write_gs3_tree, write_nrhints_tree

from olatbench.datasets import load_scene
from olatbench.datasets.convert import write_scene


def bare_decode(paths: list[Path]) -> None:
    import OpenImageIO as oiio

    for path in paths:
        image = oiio.ImageInput.open(str(path))
        spec = image.spec()
        image.read_image(0, 0, 0, spec.nchannels, "float")
        image.close()


def load_all(frames: list, colourspace: str) -> None:
    """Each frame as a method receives it; like `bare_decode`, nothing is kept
    (a streaming loader)."""
    for frame in frames:
        frame.load(colourspace=colourspace)


def best_rates(works: dict, n: int, repeats: int) -> dict[str, float]:
    """Frames per CPU-second of the fastest of ``repeats`` runs of each work, interleaved.

    CPU time (``process_time``) and interleaving keep the ratio meaningful on a machine shared with
    other jobs.
    """
    times: dict[str, list[float]] = {name: [] for name in works}
    for _ in range(repeats):
        for name, work in works.items():
            start = time.process_time()
            work()
            times[name].append(time.process_time() - start)
    return {name: n / min(values) for name, values in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=12)
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        size = (args.size, args.size)
        write_gs3_tree(tmp / "exr", n_train=args.frames, n_test=0, size=size)
        write_nrhints_tree(tmp / "png", n_train=args.frames, n_test=0, size=size)
        for kind, space, other in (("exr", "gamma22", "nrhints"), ("png", "srgb", "gs3")):
            scene = load_scene(tmp / kind)
            frames = scene.split("train")
            paths = [f.image_path for f in frames]
            counter = iter(range(10_000))

            def convert(scene=scene, other=other, counter=counter, kind=kind):
                write_scene(scene, tmp / f"out_{kind}_{next(counter)}", other)

            rates = best_rates(
                {
                    "bare": lambda paths=paths: bare_decode(paths),
                    "load": lambda frames=frames, space=space: load_all(frames, space),
                    "convert": convert,
                },
                len(frames),
                args.repeats,
            )
            bare, load, conv = rates["bare"], rates["load"], rates["convert"]
            overhead = bare / load - 1.0
            results[kind] = (bare, load, conv, overhead)
            print(
                f"{kind} {args.size}²: bare decode {bare:7.1f} frames/CPU-s | Frame.load({space}) "
                f"{load:7.1f} (overhead {overhead * 100:+.0f} %) | load+convert to {other} "
                f"{conv:6.1f}"
            )
    status = "ok" if all(r[3] <= 0.25 for r in results.values()) else "over-target"
    print(
        "BENCH datasets "
        + " ".join(
            f"{k}_bare_fps={r[0]:.1f} {k}_load_fps={r[1]:.1f} {k}_convert_fps={r[2]:.1f} "
            f"{k}_load_overhead={r[3]:.3f}"
            for k, r in results.items()
        )
        + f" target_overhead=0.25 status={status}"
    )


if __name__ == "__main__":
    main()
