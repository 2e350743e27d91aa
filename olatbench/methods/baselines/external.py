"""Run an official implementation as a separate process and map its renders back to olatbench frame ids.

External methods do not fit the in-process `Method` loop: they train and render through their own scripts in
their own environment (usually CUDA). `run_external` does everything a runner needs for one scene:

1. write the scene in the format the official loader reads (`olatbench.datasets.convert.write_scene`) into
   ``<workdir>/scene`` — frames keep their order, which is the order the official loaders enumerate them;
2. run the spec's commands (train, render, …) with ``cwd`` = the user's checkout, each logged to
   ``<workdir>/logs/<step>.log``; a non-zero exit raises `ExternalRunError` with the command line and the
   tail of its log;
3. find the render of every frame of the evaluated split from the spec's ``renders`` pattern and return
   ``{frame_id: path}`` (frame ids of the *source* scene), or raise `ExternalRunError` listing what is missing.

`export_renders` copies them to ``renders/<split>/<frame_id>.png`` of a run folder, so the metrics and reports
apply unchanged. Specs live in `olatbench.methods.baselines.external_specs`.
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from olatbench.atomic import atomic_path
from olatbench.datasets import load_scene
from olatbench.datasets.convert import write_scene
from olatbench.datasets.records import Scene
from olatbench.methods.baselines.external_specs import ExternalSpec

LOG_TAIL_LINES = 25
_SUITE_ARGS = "{*suite_args}"


class ExternalRunError(RuntimeError):
    """An external method failed: its command exited non-zero, could not start, timed out, or left renders out."""


@dataclass
class ExternalPlan:
    """What `run_external` will do: the converted ``scene_dir``, the ``model_dir`` the scripts write to, the
    ``commands`` (step name, argv) with placeholders filled, and the expected ``renders`` {frame_id: path}."""

    spec: ExternalSpec
    checkout: Path
    scene_dir: Path
    model_dir: Path
    log_dir: Path
    commands: list[tuple[str, list[str]]]
    renders: dict[str, Path]
    colourspace: str

    def describe(self) -> str:
        """The commands as shell lines (for logs and dry runs)."""
        return "\n".join(f"[{name}] (cd {shlex.quote(str(self.checkout))} && {shlex.join(argv)})"
                         for name, argv in self.commands)


def fill_command(spec: ExternalSpec, step: str, argv: tuple[str, ...], values: dict[str, str],
                 suite: str | None) -> list[str]:
    """One command line with its placeholders replaced (``{*suite_args}`` expands to zero or more arguments)."""
    filled: list[str] = []
    for arg in argv:
        if arg == _SUITE_ARGS:
            filled.extend(spec.args_for(suite, step))
            continue
        try:
            filled.append(arg.format_map(values))
        except KeyError as error:
            raise ValueError(f"external spec {spec.name!r}, step {step!r}: unknown placeholder {error} in "
                             f"{arg!r}; known: {', '.join(sorted(values))}, {_SUITE_ARGS}") from None
    return filled


def convert_scene(spec: ExternalSpec, scene: Scene, workdir: Path) -> Path:
    """Write ``scene`` for the official loader into ``<workdir>/scene`` (replacing an earlier conversion)."""
    return write_scene(scene, Path(workdir) / "scene", spec.data_format, overwrite=True)


def render_order(source: Scene, converted_dir: Path, fmt: str, split: str) -> list[tuple[str, str]]:
    """``(source frame id, written file stem)`` of every frame of ``split``, in the order the converted scene
    lists them (the order the official loader enumerates, hence of its ``{index}``)."""
    written = load_scene(converted_dir, fmt)
    if split not in source.splits:
        raise ValueError(f"scene '{source.name}' has no split '{split}'; splits: {', '.join(source.splits)}")
    original, converted = source.split(split), written.split(split)
    if len(original) != len(converted):
        raise ExternalRunError(f"{converted_dir}: the converted split '{split}' has {len(converted)} frames, the "
                               f"source {len(original)}; cannot map renders back to frame ids")
    return [(a.frame_id, b.frame_id) for a, b in zip(original, converted, strict=True)]


def plan_external(spec: ExternalSpec, scene_dir: str | Path, workdir: str | Path, checkout: str | Path, *,
                  split: str = "test", suite: str | None = None, iterations: int | None = None,
                  python: str | None = None) -> ExternalPlan:
    """Convert the scene and fill in the commands and render paths (nothing is run)."""
    workdir, checkout = Path(workdir).resolve(), Path(checkout).resolve()
    if not checkout.is_dir():
        raise ExternalRunError(f"{checkout}: no checkout of {spec.repository} here (clone it, e.g. "
                               f"'git clone {spec.repository} {checkout}', and check out commit {spec.commit})")
    source = load_scene(Path(scene_dir))
    converted = convert_scene(spec, source, workdir)
    model_dir = workdir / "model"
    values = {"python": python or sys.executable, "checkout": str(checkout), "scene": str(converted),
              "model": str(model_dir), "iterations": "" if iterations is None else str(int(iterations))}
    if iterations is None and any("{iterations}" in arg for _, argv in spec.commands for arg in argv):
        raise ValueError(f"external spec {spec.name!r} needs iterations= (its commands use {{iterations}})")
    commands = [(step, fill_command(spec, step, argv, values, suite)) for step, argv in spec.commands]
    renders = {}
    for index, (frame_id, stem) in enumerate(render_order(source, converted, spec.data_format, split)):
        renders[frame_id] = Path(spec.renders.format(index=index, stem=stem, **values))
    return ExternalPlan(spec=spec, checkout=checkout, scene_dir=converted, model_dir=model_dir,
                        log_dir=workdir / "logs", commands=commands, renders=renders,
                        colourspace=spec.colourspace_for(suite))


def log_tail(path: Path, lines: int = LOG_TAIL_LINES) -> str:
    """The last ``lines`` lines of a log file ("" when it does not exist)."""
    if not path.is_file():
        return ""
    return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])


def run_command(step: str, argv: list[str], cwd: Path, log_path: Path, env: dict[str, str] | None = None,
                timeout: float | None = None) -> None:
    """Run one command with stdout and stderr appended to ``log_path``; `ExternalRunError` on any failure."""
    log_path.parent.mkdir(parents=True, exist_ok=True)
    line = shlex.join(argv)
    with log_path.open("w") as log:
        log.write(f"$ (cd {shlex.quote(str(cwd))} && {line})\n")
        log.flush()
        try:
            completed = subprocess.run(argv, cwd=cwd, stdout=log, stderr=subprocess.STDOUT,
                                       env={**os.environ, **(env or {})}, timeout=timeout, check=False)
        except FileNotFoundError as error:
            raise ExternalRunError(f"{step}: cannot start {argv[0]!r} ({error.strerror}); command: {line}") from None
        except subprocess.TimeoutExpired:
            raise ExternalRunError(f"{step}: timed out after {timeout} s; command: {line}\nlog: {log_path}\n"
                                   f"{log_tail(log_path)}") from None
    if completed.returncode != 0:
        raise ExternalRunError(f"{step} failed with exit code {completed.returncode}\ncommand: {line}\n"
                               f"log: {log_path} (last {LOG_TAIL_LINES} lines below)\n{log_tail(log_path)}")


def collect_renders(plan: ExternalPlan) -> dict[str, Path]:
    """The expected renders, checked to exist; `ExternalRunError` listing the missing ones otherwise."""
    missing = [(frame_id, path) for frame_id, path in plan.renders.items() if not path.is_file()]
    if missing:
        shown = "\n".join(f"  {frame_id}: {path}" for frame_id, path in missing[:5])
        folder = missing[0][1].parent
        found = sorted(p.name for p in folder.iterdir())[:10] if folder.is_dir() else []
        raise ExternalRunError(
            f"{plan.spec.name}: {len(missing)} of {len(plan.renders)} renders are missing (pattern "
            f"{plan.spec.renders!r}), e.g.\n{shown}\n{folder} holds: {', '.join(found) if found else 'nothing'}")
    return dict(plan.renders)


def run_external(spec: ExternalSpec, scene_dir: str | Path, workdir: str | Path, checkout: str | Path, *,
                 split: str = "test", suite: str | None = None, iterations: int | None = None,
                 python: str | None = None, timeout: float | None = None) -> dict[str, Path]:
    """Convert the scene, run the official scripts, and return ``{frame_id: render path}`` for ``split``.

    ``suite`` selects the spec's suite arguments and render colour space; ``python`` is the interpreter of the
    official environment (default: this one); ``timeout`` (s) applies to each command.
    """
    plan = plan_external(spec, scene_dir, workdir, checkout, split=split, suite=suite, iterations=iterations,
                         python=python)
    for step, argv in plan.commands:
        run_command(step, argv, plan.checkout, plan.log_dir / f"{step}.log", spec.env, timeout)
    return collect_renders(plan)


def export_renders(renders: dict[str, Path], out_dir: str | Path) -> dict[str, Path]:
    """Copy renders to ``<out_dir>/<frame_id><suffix>`` atomically (the run-folder layout); returns the copies."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    copies = {}
    for frame_id, source in renders.items():
        target = out_dir / f"{frame_id}{source.suffix}"
        with atomic_path(target) as temporary:
            shutil.copyfile(source, temporary)
        copies[frame_id] = target
    return copies


__all__ = ["ExternalPlan", "ExternalRunError", "collect_renders", "export_renders", "plan_external", "run_external"]
