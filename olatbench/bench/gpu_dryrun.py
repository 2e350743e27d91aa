"""The fake-CUDA dry run of the Gaussian methods' GPU path: every host sync and device mix of a
training step, found on any machine (`olatbench doctor --fake-cuda`; docs/gpu.md).

For SSD-GS (its ``nrhints`` preset: camera-matched light framing, camera and light refinement, test
views fitted during training, a count cap), GS³ (its light view fitted to the Gaussians) and 3DGS,
on a few views of the closed-form sphere (`olatbench.datasets.synth.analytic`) shortened to
`ITERATIONS` steps, under `olatbench.gaussians.fake_cuda.fake_cuda` on ``device="cuda"``: ``setup``;
``train_step`` at the first step, then at the first densification step after every schedule phase
has begun (SSD-GS's and GS³'s terms, frozen windows and refinements, 3DGS's SH degrees), and the
step after it (with two training views the second of these starts a new epoch, and SSD-GS's
``nrhints`` preset fits its test views there); after each step the runner's logging read
(`olatbench.bench.execute.read_scalars`); and one ``render``. The light-view pass runs inside
SSD-GS's and GS³'s steps and renders once the shadow term is on: framed by the camera
(SSD-GS ``nrhints``) and fitted to the Gaussians (GS³; SSD-GS's ``mini`` preset frames it the same
way, through the same code).

A finding fails the run (`DryRun.violations`) when it is a device mix anywhere, or a host sync
inside a step or a render outside the allowances named in `olatbench.gaussians.host_sync`
(or over an allowance's limit).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from olatbench.bench.execute import read_scalars
from olatbench.datasets.synth.analytic import render_sphere, sphere_rig
from olatbench.methods.base import Views

ITERATIONS = 100  # the schedules scaled to this many steps: every phase begins by step 22
#: (label, method, preset, overrides): small models and light views; 3DGS raises its SH degree every
#: 5 steps.
CASES: tuple[tuple[str, str, str | None, dict[str, Any]], ...] = (
    ("ssdgs", "ssdgs", "nrhints", {"shadow_resolution": 16, "max_gaussians": 80}),
    ("gs3", "gs3", None, {"shadow_resolution": 16}),
    ("3dgs", "3dgs", None, {"sh_increase_interval": 5}),
)
ALL_PHASES_FROM = 23  # first step with every phase of every case begun (at ITERATIONS)
GAUSSIANS, SIZE, TRAIN_VIEWS = 64, 24, 2


@dataclass
class DryRun:
    """What the dry run did (``log``: one line per stage) and found (``findings``, in order);
    ``errors``: a case that stopped with an exception (its message)."""

    findings: list = field(default_factory=list)
    log: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    def violations(self) -> list:
        """Device mixes, and syncs of a step or render outside an allowance or over its limit."""
        return [
            f
            for f in self.findings
            if f.kind == "device mix"
            or (
                f.kind == "sync"
                and f.phase.split(": ", 1)[-1].startswith(("train_step", "render"))
                and (f.allowance is None or f.over_limit)
            )
        ]

    def report(self) -> str:
        """A readable report: the stages, every finding (file:line), the violations and errors."""
        lines = ["fake-CUDA dry run of the GPU path (docs/gpu.md)", *self.log, "", "findings:"]
        lines += [f"  {f.line()}" for f in self.findings] or ["  none"]
        bad = self.violations()
        lines += [
            "",
            f"violations ({len(bad)}): device mixes, and host syncs in a step or render outside "
            "the allowances of olatbench.gaussians.host_sync",
        ]
        lines += [f"  {f.line()}" for f in bad]
        lines += [f"error: {e}" for e in self.errors]
        return "\n".join(lines)


def sphere_views(n: int, seed: int) -> Views:
    """``n`` views of the closed-form Lambertian sphere, ``SIZE``² pixels, black background."""
    cameras, lights = sphere_rig(n, SIZE, seed)
    images = np.stack([render_sphere(c, lt) for c, lt in zip(cameras, lights, strict=True)]).astype(
        np.float32
    )
    return Views(
        cameras=cameras,
        lights=lights,
        images=images,
        frame_ids=[f"{seed}-{i}" for i in range(n)],
        scene_name="lambert-sphere",
    )


def densification_step(method: Any, start: int) -> int:
    """The first step ≥ ``start`` whose density control densifies (its iteration is step + 1)."""
    cfg = method.densifier.config
    for step in range(start, cfg.densify_until - 1):
        if step + 1 > cfg.densify_from and (step + 1) % cfg.densify_interval == 0:
            return step
    raise ValueError(f"no densification step from {start} before {cfg.densify_until}")


def _case(
    label: str, name: str, preset: str | None, overrides: dict[str, Any], run: DryRun, recorder: Any
) -> None:
    from olatbench.methods.registry import get_spec

    spec = get_spec(name)
    config = spec.resolve_config(
        preset, iterations=ITERATIONS, num_init_gaussians=GAUSSIANS, **overrides
    )
    method = spec.load_implementation()(config)
    train, test = sphere_views(TRAIN_VIEWS, seed=0), sphere_views(1, seed=1)
    if name == "ssdgs":
        method.attach_test_views(test)
    recorder.phase = f"{label}: setup"
    method.setup(train, "cuda", 0)
    step = densification_step(method, ALL_PHASES_FROM)
    for at in (0, step, step + 1):
        recorder.phase = f"{label}: train_step {at}"
        result = method.train_step(at)
        recorder.phase = f"{label}: logging after step {at}"
        read_scalars(result)
    run.log.append(
        f"{label}: setup, train_step 0, {step} (densifies), {step + 1}; {method.num_gaussians} "
        f"Gaussians (fake count); backends {method.backends()}"
    )
    recorder.phase = f"{label}: render"
    method.render(test.cameras[0], test.lights[0])


def dry_run(cases: tuple[tuple[str, str, str | None, dict[str, Any]], ...] = CASES) -> DryRun:
    """Run `CASES` (or ``cases``) under fake CUDA; returns what was found
    (see the module docstring). Raises ``olatbench._native.BuildError`` when the no-op CUDA guard
    cannot be built, ImportError without gsplat."""
    from olatbench.gaussians.fake_cuda import fake_cuda

    run = DryRun()
    with fake_cuda() as recorder:
        for label, name, preset, overrides in cases:
            try:
                _case(label, name, preset, overrides, run, recorder)
            except Exception as error:
                run.errors.append(f"{recorder.phase}: {type(error).__name__}: {error}")
    run.findings = list(recorder.findings)
    return run


__all__ = ["CASES", "DryRun", "dry_run", "sphere_views"]
