"""How long a planned job will train on this machine: a short measurement, stored, and a step-count
model.

`calibrate` (imports torch; seconds to a minute) times the job's own method on a few of the job's
own training views at the job's resolution, with the density control's statistics gathered as in
training but no Gaussian added, removed or reset (so N stays put), at two model sizes — the config's
initial Gaussian count and its cap (``max_gaussians``; 4× the initial count when the config has no
cap) — and at three points of the schedule (10 %, 50 % and 90 % of the iterations, since terms
switch on and off along it). The model is timed as a trained one looks, a closed nearly opaque
surface (`olatbench.gaussians.surface`) in the initial ball, not as the initial cloud: at opacity
0.1 that cloud blends many Gaussians per pixel and stepped 2.1× slower than the trained model of the
same size on mini (the estimate was 1.8× too high on an Intel Xeon for that reason). It fits seconds
per step as ``a + b·N`` and stores that per machine and per (method, config, resolution, device) in
``$XDG_CACHE_HOME/olatbench/calibration.json``, together with the device ``--device auto`` named on
the machine when it was measured (``"auto_devices": {machine: "cpu" | "cuda"}``): naming it needs
torch, which a plain dry run never imports, so a dry run with ``auto`` reads the stored name instead
(none stored: no estimate, ``--calibrate`` stores it).

`estimate` (torch-free, for ``olatbench run --dry-run``) sums ``a + b·N(step)`` over the job's steps
with the Gaussian count modelled as the config's initial count until the first densification (the
first multiple of ``densify_interval`` in the window), growing linearly to the cap at
``densify_until`` and constant after (the windows as the method scales them). Methods without a
Gaussian count are timed at their one size. The estimate covers training only — not loading the
views, the checkpoints nor the evaluation — and inherits the two models' errors: the first few
hundred steps, while the initial cloud settles, are slower than the surface, and a run that stays
well below its cap trains faster than estimated.
"""

from __future__ import annotations

import json
import os
import platform
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from olatbench.atomic import write_json
from olatbench.bench.jobs import Job, hash_json
from olatbench.devices import AUTO, resolve_device

CALIBRATION_FILE = "calibration.json"
# the file's key of what --device auto named on each machine (module docstring)
AUTO_DEVICES = "auto_devices"
SCHEDULE_POINTS = (0.1, 0.5, 0.9)
STEPS_PER_POINT = 2
CALIBRATION_VIEWS = 4
# the calibration's surface, as a fraction of the initial ball's radius (bench_ssdgs's state)
SURFACE_RADIUS = 0.8
UNCAPPED_GROWTH = 4  # the size measured for a config with no cap: this many times its initial count
DAY_SECONDS = 86_400.0


@dataclass(frozen=True)
class StepCost:
    """Seconds per training step ``a + b·N`` of one job's method, config and resolution on one
    machine."""

    a: float
    b: float
    measured: dict[str, float]  # Gaussian count (as text) -> mean seconds per step

    def seconds(self, gaussians: float) -> float:
        return self.a + self.b * gaussians


def machine_id() -> str:
    """The machine a calibration belongs to: host name, CPU architecture, processor and core
    count."""
    return f"{platform.node()}|{platform.machine()}|{platform.processor()}|{os.cpu_count()}"


def calibration_path() -> Path:
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "olatbench" / CALIBRATION_FILE


def cost_key(job: Job) -> str:
    """What a calibration depends on besides the machine: method, config (without the seed) and
    resolution."""
    return hash_json(
        {
            "method": job.method,
            "config": job.config,
            "resolution": job.resolution,
            "device": job.device,
        }
    )


def load_costs(path: Path | None = None) -> dict[str, StepCost]:
    """This machine's stored calibrations, by `cost_key` (empty when none)."""
    path = calibration_path() if path is None else path
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return {}
    return {key: StepCost(**value) for key, value in stored.get(machine_id(), {}).items()}


def stored_auto_device(path: Path | None = None) -> str | None:
    """The device ``--device auto`` named on this machine when a calibration was last measured
    (None: never)."""
    path = calibration_path() if path is None else path
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return None
    named = stored.get(AUTO_DEVICES, {}).get(machine_id()) if isinstance(stored, dict) else None
    return named if isinstance(named, str) else None


def save_cost(job: Job, cost: StepCost, path: Path | None = None, auto: str | None = None) -> None:
    """Add one calibration to the machine's entry (the file is rewritten atomically); ``auto``: the
    device ``--device auto`` names on this machine, stored beside it."""
    path = calibration_path() if path is None else path
    try:
        stored = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        stored = {}
    stored.setdefault(machine_id(), {})[cost_key(job)] = {
        "a": cost.a,
        "b": cost.b,
        "measured": cost.measured,
    }
    if auto is not None:
        stored.setdefault(AUTO_DEVICES, {})[machine_id()] = auto
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, stored)


def gaussian_counts(config: Any) -> tuple[int, int] | None:
    """(initial, cap) Gaussian counts of a method config, or None for a method without them."""
    if not hasattr(config, "num_init_gaussians"):
        return None
    initial = int(config.num_init_gaussians)
    cap = getattr(config, "max_gaussians", None)
    return initial, int(cap) if cap else UNCAPPED_GROWTH * initial


def estimate_seconds(config: Any, cost: StepCost) -> float:
    """Training seconds of a run of ``config`` (the method's config object) under ``cost``; see the
    module docstring for the growth model. The densification window is the config's own, scaled by
    its ``steps``."""
    steps = int(config.iterations)
    counts = gaussian_counts(config)
    if counts is None:
        return steps * cost.seconds(0.0)
    initial, cap = counts
    start = end = steps
    if hasattr(config, "density_windows"):
        windows = config.density_windows()
        interval = windows.interval
        # the first densification step
        start = min(steps, -(-windows.densify_from // interval) * interval)
        end = min(steps, max(start, windows.densify_until))
    ramp = end - start
    # before the first densification at the initial count, then a linear ramp to the cap (its mean),
    # then the cap
    return (
        start * cost.seconds(initial)
        + ramp * cost.seconds((initial + cap) / 2)
        + (steps - end) * cost.seconds(cap if ramp > 0 else initial)
    )


def calibrate(job: Job, views: Any | None = None, progress: bool = True) -> StepCost:
    """Measure ``job``'s method on this machine (module docstring) and return its step cost
    (not stored)."""
    import torch

    from olatbench.bench.execute import load_views
    from olatbench.bench.plan import load_method_class
    from olatbench.datasets import load_scene

    if views is None:
        frames = load_scene(job.scene_path, format=job.scene_format).split(job.train_split)[
            :CALIBRATION_VIEWS
        ]
        views = load_views(frames, job)
    method_class = load_method_class(job)
    base = method_class.resolve_config(None, **job.config)
    counts = gaussian_counts(base)
    sizes = sorted(set(counts)) if counts is not None else [0]
    never = 10**12
    iterations = int(base.iterations)
    measured: dict[str, float] = {}
    for size in sizes:
        config = base
        if counts is not None:
            config = replace(
                base,
                num_init_gaussians=size,
                densify_from=never,
                densify_interval=never,
                opacity_reset_interval=never,
            )
        method = method_class(config)
        method.setup(views, job.device, job.seed)
        if counts is not None:
            _as_trained_surface(method, views, config)
        seconds = []
        for fraction in SCHEDULE_POINTS:
            step = max(1, min(iterations - 1, int(fraction * iterations)))
            method.train_step(step)  # warm-up at this point of the schedule
            for _ in range(STEPS_PER_POINT):
                clock = time.perf_counter()
                method.train_step(step)
                if str(job.device).startswith("cuda"):
                    torch.cuda.synchronize(job.device)
                seconds.append(time.perf_counter() - clock)
        # the median: robust to a passing load
        measured[str(size)] = sorted(seconds)[len(seconds) // 2]
        if progress:
            print(
                f"calibration {job.method} {job.variant}: N={size}: {measured[str(size)]:.3f} "
                "s/step",
                flush=True,
            )
        del method
    if len(sizes) == 1:
        return StepCost(a=measured[str(sizes[0])], b=0.0, measured=measured)
    (n0, t0), (n1, t1) = ((int(n), t) for n, t in measured.items())
    slope = max(0.0, (t1 - t0) / (n1 - n0))
    return StepCost(a=t0 - slope * n0, b=slope, measured=measured)


def _as_trained_surface(method: Any, views: Any, config: Any) -> None:
    """Make a Gaussian method's model the trained-looking stand-in: a closed surface of 0.8× the
    radius of the ball its Gaussians were initialised in, around the same centre
    (module docstring)."""
    from olatbench.gaussians.surface import place_on_sphere
    from olatbench.methods.initialisation import initial_ball

    # as the model
    centre, radius = initial_ball(views.in_frame().cameras, getattr(config, "init_radius", None))
    place_on_sphere(method.model, centre.tolist(), SURFACE_RADIUS * radius)


def format_duration(seconds: float) -> str:
    """``3 d 4 h``, ``5 h 12 min``, ``12 min``, ``40 s``."""
    if seconds >= DAY_SECONDS:
        return f"{int(seconds // DAY_SECONDS)} d {int(seconds % DAY_SECONDS // 3600)} h"
    if seconds >= 3600:
        return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60)} min"
    if seconds >= 60:
        return f"{round(seconds / 60)} min"
    return f"{round(seconds)} s"


def plan_estimates(
    jobs: list[Job], measure: bool = False, progress: bool = True
) -> list[float | None]:
    """Estimated training seconds of each job from this machine's stored calibrations
    (None where there is none); ``measure`` calibrates (and stores) the missing ones first — jobs
    need their data for that.

    Without ``measure`` no torch is imported: a job's ``auto`` device is named from the calibration
    file (module docstring)."""
    from olatbench.methods.registry import config_class, get_spec

    costs = load_costs()
    auto = resolve_device(AUTO) if measure else stored_auto_device()
    estimates: list[float | None] = []
    for job in jobs:
        if job.official is not None:  # the authors' code: not timed by olatbench's calibration
            estimates.append(None)
            continue
        device = auto if job.device == AUTO else job.device
        if device is None:  # "auto", never named on this machine by a calibration
            estimates.append(None)
            continue
        job = replace(job, device=device)  # calibrations name the device they ran on: never "auto"
        key = cost_key(job)
        if key not in costs and measure:
            if not job.scene_path:
                raise ValueError(
                    f"{job.label}: the scene's data is missing, so the job cannot be timed"
                )
            costs[key] = calibrate(job, progress=progress)
            save_cost(job, costs[key], auto=auto)
        if key not in costs:
            estimates.append(None)
            continue
        # torch-free: the spec's config dataclass
        config = config_class(get_spec(job.method))(**job.config)
        estimates.append(estimate_seconds(config, costs[key]))
    return estimates
