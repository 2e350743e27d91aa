"""SSD-GS at the paper's scale on this machine: seconds per training step by stage, and peak memory.

For each suite (``--suites``, default nrhints gs3 sssgs) the script loads the suite's stand-in
(`olatbench.datasets.synth.standins`: the suite's format, image size and training-image count,
rendered once and cached) through the runner's own loader, sets SSD-GS up with the suite's preset,
and for each Gaussian count (``--counts``, default 100K, 300K and 550K — the densification cap)
makes the model a trained-looking closed surface of that many Gaussians (as ``bench_ssdgs.py``'s
``surface`` state). It then times ``--steps`` complete ``train_step`` calls at an iteration where
every term is on (densification off, so N stays fixed) and splits one step into stages with
``bench_ssdgs.py``'s stage functions (camera pass, light-view pass, the two networks, Adam, and
``rest`` = the step with free stand-ins for the networks). Each case runs in its own process, so the
peak resident memory it reports (``ru_maxrss``) is that case's alone: the training images (float32,
as the runner holds them), the model, Adam's state and one step's autograd graph.

Ratios printed against references measured in the same run: ``step/raster`` (the whole step in units
of the camera pass alone) and ``rss/images`` (peak memory in units of the image stack); ``run at N``
is the suite's iteration count at that step time (an upper bound for a run that reaches N Gaussians
late); ``prec`` the networks' precision (``--precisions``) and ``light pass`` the backend the
preset's light-view pass ran on. The last line is a parseable summary with the worst peak memory at
512² (target: ≤ 8 GiB with 550K Gaussians). Examples::

    python benchmarks/bench_scale.py                           # the three suites, 100K/300K/550K
    python benchmarks/bench_scale.py --suites gs3 --counts 550000 --steps 3
    python benchmarks/bench_scale.py --suites nrhints --images 100   # quicker (fewer images)
    python benchmarks/bench_scale.py --images 100 --fill-stack       # the suites' full memory
    python benchmarks/bench_scale.py --suites sssgs --precisions fp32 bf16   # both precisions

``--fill-stack`` repeats the rendered training frames until the stack has the suite's realistic
count (`STANDINS`): each image is read and held as often as a distinct one would be, so the stack's
memory, its float16 switch and the step (which reads one image) are those of the full count, without
rendering it.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import resource
import subprocess
import sys
import tempfile
import time

ALL_ON_STEP = 30_000  # the 100K schedule: every term on, camera/light refinement on, nothing frozen


def analytic_views(suite: str, distinct: int):
    """The suite's stand-in size and training-image count with closed-form images (the Lambertian
    sphere of `olatbench.datasets.synth.analytic`): ``distinct`` rendered views repeated up to the
    suite's count, as ``--fill-stack`` does. Needs no Mitsuba (a GPU node); the step's cost does not
    depend on what the images show."""
    import numpy as np

    from olatbench.datasets.synth.analytic import render_sphere, sphere_rig
    from olatbench.datasets.synth.standins import STANDINS
    from olatbench.methods.base import Views

    standin = STANDINS[suite]
    cameras, lights = sphere_rig(distinct, standin.resolution, seed=0)
    rendered = [render_sphere(c, lt) for c, lt in zip(cameras, lights, strict=True)]
    order = [index % distinct for index in range(standin.train)]
    images = np.stack([rendered[index] for index in order])
    return Views(
        cameras=[cameras[i] for i in order],
        lights=[lights[i] for i in order],
        images=images,
        frame_ids=[f"{i:05d}" for i in range(standin.train)],
        background=np.zeros(3, dtype=np.float32),
        scene_name=f"{suite}-analytic",
    )


def stand_in_views(suite: str, images: int | None, fill_stack: bool):
    """The suite's rendered stand-in (Mitsuba, cached) loaded through the runner's own loader, and
    the centre of its object's bounding sphere."""
    from olatbench.bench.execute import load_views
    from olatbench.bench.jobs import Job
    from olatbench.datasets import load_scene
    from olatbench.datasets.suites import get_suite
    from olatbench.datasets.synth.standins import STANDINS, ensure_standin

    suite_record = get_suite(suite)
    folder = ensure_standin(suite, train=images, progress=False)
    scene = load_scene(folder)
    frames = scene.split(suite_record.train_split)
    # the rendered frames again and again, up to the suite's realistic training-image count
    if fill_stack:
        target = STANDINS[suite].train
        frames = [frames[index % len(frames)] for index in range(target)]
    job = Job(
        method="ssdgs",
        method_ref="",
        suite=suite,
        scene=folder.name,
        variant="default",
        seed=0,
        config={},
        scene_path=str(folder),
        scene_format=suite_record.format,
        colourspace=suite_record.colourspace,
        resolution=suite_record.resolution,
        train_split=suite_record.train_split,
        test_split=suite_record.test_split,
        protocol="",
        protocol_version=0,
        data_manifest=None,
        code="",
        # where a memory-mapped image stack would go
        folder=tempfile.mkdtemp(prefix="bench_scale_"),
    )
    centre = json.loads((folder / "synth.json").read_text())["object_bounding_sphere"]["centre"]
    return load_views(frames, job), centre


def synchronised(device, fn):
    """``fn`` followed by a wait for the device's queued work (CUDA runs asynchronously), so a host
    clock around the call measures the work itself."""
    import torch

    if torch.device(device).type != "cuda":
        return fn

    def run():
        out = fn()
        torch.cuda.synchronize(device)
        return out

    return run


def run_case(
    suite: str,
    count: int,
    steps: int,
    repeats: int,
    images: int | None,
    threads: int,
    fill_stack: bool = False,
    precision: str = "fp32",
    device: str = "cpu",
    analytic: bool = False,
) -> dict:
    """One (suite, Gaussian count) case in this process; returns its measurements as plain
    numbers."""
    import torch
    from bench_ssdgs import (
        mlp_stage,
        optimizer_stage,
        put_on_sphere,
        raster_stage,
        rest_stage,
        shadow_stage,
        starting_clean,
        timed,
    )

    from olatbench.bench.plan import resolve_config
    from olatbench.datasets.suites import get_suite
    from olatbench.methods.registry import get_spec
    from olatbench.methods.ssdgs import SSDGS

    torch.set_num_threads(threads)
    torch.set_flush_denormal(True)
    clock = time.perf_counter()
    if analytic:
        views, centre = analytic_views(suite, images or 100), [0.0, 0.0, 0.0]
    else:
        views, centre = stand_in_views(suite, images, fill_stack)
    load_seconds = time.perf_counter() - clock
    never = 10**9
    config = resolve_config(get_spec("ssdgs"), get_suite(suite))
    config = dataclasses.replace(
        config,
        num_init_gaussians=count,
        max_gaussians=None,
        densify_from=never,
        densify_until=never,
        opacity_reset_interval=never,
        network_precision=precision,
    )
    method = SSDGS(config)
    method.setup(views, device, 0)
    if torch.device(device).type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)
    put_on_sphere(method, radius=0.8, opacity=0.9)
    # onto the scene's object (the generator's bounding sphere, radius 1; the analytic sphere)
    with torch.no_grad():
        method.model.means += torch.tensor(
            centre, dtype=torch.float32, device=method.model.means.device
        )
    visible = torch.arange(method.model.num_gaussians)
    stages = {
        "raster": raster_stage(method),
        "shadow": shadow_stage(method),
        "mlp": mlp_stage(method, visible),
        "optim": optimizer_stage(method),
        "rest": rest_stage(method, ALL_ON_STEP),
    }
    stage_seconds = timed(
        {name: synchronised(device, starting_clean(method, fn)) for name, fn in stages.items()},
        repeats,
    )
    train_step = synchronised(device, lambda: method.train_step(ALL_ON_STEP + len(step_seconds)))
    step_seconds: list[float] = []
    for _ in range(steps + 1):  # the first is a warm-up
        clock = time.perf_counter()
        train_step()
        step_seconds.append(time.perf_counter() - clock)
    render_fps = measure_render_fps(method, views, device, repeats)
    camera = views.cameras[0]
    cuda = torch.device(device).type == "cuda"
    return {
        "suite": suite,
        "gaussians": method.model.num_gaussians,
        "width": camera.width,
        "height": camera.height,
        "images": len(views),
        "image_gib": views.images.nbytes / 2**30,
        "load_seconds": load_seconds,
        "step_seconds": min(step_seconds[1:]),
        "step_seconds_mean": sum(step_seconds[1:]) / steps,
        "stages": stage_seconds,
        "peak_rss_gib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
        "peak_device_gib": torch.cuda.max_memory_allocated(device) / 2**30 if cuda else None,
        "render_fps": render_fps,
        "device": device,
        "analytic": analytic,
        "threads": threads,
        "precision": precision,
        "light_pass": light_pass_backend(method),
    }


def measure_render_fps(method, views, device: str, repeats: int) -> float:
    """Frames per second of ``method.render`` (every component, no gradients) over the first
    training views: the median of ``max(repeats, 5)`` renders after one warm-up."""
    import statistics

    import torch

    frames = [
        (views.cameras[i % len(views)], views.lights[i % len(views)])
        for i in range(max(repeats, 5) + 1)
    ]
    seconds = []
    with torch.no_grad():
        for camera, light in frames:
            render = synchronised(
                device, lambda camera=camera, light=light: method.render(camera, light)
            )
            clock = time.perf_counter()
            render()
            seconds.append(time.perf_counter() - clock)
    return 1.0 / statistics.median(seconds[1:])


def light_pass_backend(method) -> str:
    """The backend the method's light-view pass runs on (its mode decides: ``"footprint"`` is
    torch-only)."""
    from olatbench.gaussians.shadow import shadow_gather
    from olatbench.methods.training import camera_centre

    model, views = method.model, method.train_views
    camera = views.views.cameras[0]
    light = views.light_positions[0]
    options = method.light_view_options(
        views.Ks[0], camera.width, camera.height, camera_centre(views.w2cs[0]), light
    )
    return shadow_gather(
        model.means[:1],
        model.quats[:1],
        model.scales[:1],
        model.opacities[:1],
        light,
        model.means[:1].mean(0),
        **options,
    ).backend


def main() -> None:
    from olatbench.bench.estimate import format_duration
    from olatbench.datasets.suites import get_suite

    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--suites", nargs="+", default=["nrhints", "gs3", "sssgs"])
    parser.add_argument("--counts", type=int, nargs="+", default=[100_000, 300_000, 550_000])
    parser.add_argument(
        "--steps", type=int, default=5, help="timed training steps per case (after one warm-up)"
    )
    parser.add_argument(
        "--repeats", type=int, default=2, help="rounds of the stage timings (fastest kept)"
    )
    parser.add_argument(
        "--images",
        type=int,
        default=None,
        help="training images of the stand-in (default: the suite's realistic count)",
    )
    parser.add_argument(
        "--fill-stack",
        action="store_true",
        help=(
            "repeat the rendered training frames up to the suite's realistic count (with --images)"
        ),
    )
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument(
        "--precisions",
        nargs="+",
        default=["fp32"],
        choices=["fp32", "bf16", "fp16"],
        help="network_precision of each case (e.g. fp32 bf16: every case twice)",
    )
    parser.add_argument(
        "--device", default="cpu", help="torch device of the model and images (cpu, cuda, cuda:1)"
    )
    parser.add_argument(
        "--analytic",
        action="store_true",
        help="closed-form images of the suite's size and count instead of the Mitsuba stand-in "
        "(no Mitsuba needed: a GPU node); --images distinct views (default 100)",
    )
    parser.add_argument(
        "--json", metavar="FILE", help="also write every case's measurements to FILE"
    )
    parser.add_argument(
        "--case", nargs=3, metavar=("SUITE", "COUNT", "PRECISION"), help=argparse.SUPPRESS
    )
    args = parser.parse_args()
    if args.case:  # child process: one case, one JSON line
        print(
            json.dumps(
                run_case(
                    args.case[0],
                    int(args.case[1]),
                    args.steps,
                    args.repeats,
                    args.images,
                    args.threads,
                    args.fill_stack,
                    args.case[2],
                    args.device,
                    args.analytic,
                )
            )
        )
        return
    print(
        f"{'suite':>8} {'size':>9} {'images':>6} {'N':>7} {'prec':>4} {'step':>7} {'raster':>7} "
        f"{'shadow':>7} {'mlp':>7} {'optim':>7} {'rest':>7} {'step/rast':>9} {'rss GiB':>8} "
        f"{'rss/img':>7} {'run at N':>10} {'light pass':>10} {'dev GiB':>7} {'fps':>6}"
    )
    worst_512 = 0.0
    cases = []
    for suite, count, precision in itertools.product(args.suites, args.counts, args.precisions):
        command = [
            sys.executable,
            __file__,
            "--case",
            suite,
            str(count),
            precision,
            "--steps",
            str(args.steps),
            "--repeats",
            str(args.repeats),
            "--threads",
            str(args.threads),
        ]
        if args.images is not None:
            command += ["--images", str(args.images)]
        if args.fill_stack:
            command.append("--fill-stack")
        if args.analytic:
            command.append("--analytic")
        command += ["--device", args.device]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            raise SystemExit(f"case {suite} N={count} {precision} failed:\n{done.stderr[-3000:]}")
        case = json.loads(done.stdout.strip().splitlines()[-1])
        case["projected_seconds"] = case["step_seconds"] * get_suite(suite).iterations
        cases.append(case)
        stages = case["stages"]
        if max(case["width"], case["height"]) >= 512:
            worst_512 = max(worst_512, case["peak_rss_gib"])
        print(
            f"{suite:>8} {case['width']:>4}×{case['height']:<4} {case['images']:>6} "
            f"{case['gaussians']:>7} {precision:>4} {case['step_seconds']:>6.2f}s "
            f"{stages['raster']:>6.2f}s {stages['shadow']:>6.2f}s {stages['mlp']:>6.2f}s "
            f"{stages['optim']:>6.2f}s {stages['rest']:>6.2f}s "
            f"{case['step_seconds'] / stages['raster']:>9.1f} {case['peak_rss_gib']:>8.2f} "
            f"{case['peak_rss_gib'] / case['image_gib']:>7.2f} "
            f"{format_duration(case['step_seconds'] * get_suite(suite).iterations):>10} "
            f"{case['light_pass']:>10} {case['peak_device_gib'] or 0.0:>7.2f} "
            f"{case['render_fps']:>6.1f}",
            flush=True,
        )
    if args.json:
        from olatbench.atomic import write_json

        write_json(args.json, {"device": args.device, "analytic": args.analytic, "cases": cases})
    print(
        f"SUMMARY bench_scale peak_rss_512_max_gib={worst_512:.2f} (target<=8) "
        f"threads={args.threads} counts={','.join(map(str, args.counts))} "
        f"stack={'filled' if args.fill_stack else 'rendered'} device={args.device} "
        f"images={'analytic' if args.analytic else 'stand-in'}"
    )


if __name__ == "__main__":
    main()
