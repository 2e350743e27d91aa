"""One run of an official implementation on one scene: convert, fill in the commands, run them, find
the renders.

Layout below the job's working folder ``work`` (``<job folder>/official``): ``scene/`` the converted
scene, ``model/`` what the official scripts write, ``steps/<step>.json`` one file per command that
finished (exit code 0: its argument list and wall time), written after it. The official scripts
cannot resume a command, but a job can resume between commands: `prepare` keeps ``model/`` when the
first commands of the job are recorded in ``steps/`` with the same argument lists, and marks them
done, so a rerun redoes only the commands that did not finish (RNG's stage 2 and render after its
stage 1); otherwise it starts from an empty ``work`` folder. The scene is written anew either way.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from olatbench.atomic import write_json
from olatbench.datasets.records import Frame, Scene
from olatbench.datasets.suites import SUITES
from olatbench.methods.official.code import OfficialCode, OfficialConfig
from olatbench.methods.official.convert import check_ground_truths, pair_renders, write_for_code
from olatbench.methods.official.process import CommandRecord, OfficialRunError, run_command
from olatbench.methods.official.settings import CodeSettings


@dataclass
class OfficialRun:
    """What `execute` runs: the filled-in ``commands`` with the extra environment variables ``env``
    (the code's own, and for ``device=cpu`` the stand-ins':
    `olatbench.methods.official.cpu_standins.job_environment`); the test split's ``frame_ids`` and
    ``render_order``, the transforms file whose frame order numbers the renders (read by `collect`),
    which hold values encoded as ``colourspace``; ``values`` fill the render pattern."""

    code: OfficialCode
    settings: CodeSettings
    work: Path
    scene_dir: Path
    model_dir: Path
    commands: list[CommandRecord]
    frame_ids: list[str]
    render_order: Path
    values: dict[str, object]
    colourspace: str
    env: dict[str, str]


def prepare(
    code: OfficialCode,
    settings: CodeSettings,
    source: Scene,
    work: Path,
    suite: str,
    train_split: str,
    test_split: str,
    resolution: tuple[int, int] | None,
    config: OfficialConfig,
    seed: int = 0,
) -> OfficialRun:
    """Empty ``work``, write the scene for ``code`` (with ``config.init_points`` initial points
    drawn from ``seed``) and fill in its commands and render paths (runs nothing)."""
    if not code.runnable:
        raise OfficialRunError(f"{code.name} cannot be run: {code.unsupported}")
    problems = settings.problems() + config_problems(code, config)
    if problems:
        raise OfficialRunError(f"{code.name}: " + "; ".join(problems) + " (see docs/official.md)")
    work = Path(work).resolve()
    checkout = Path(str(settings.checkout)).expanduser().resolve()
    scene_dir, model_dir = work / "scene", work / "model"
    lengths = (
        None
        if config.reference_iterations is None
        else (int(config.iterations), int(config.reference_iterations))
    )
    values: dict[str, object] = {
        "scene": str(scene_dir),
        "model": str(model_dir),
        "checkout": str(checkout),
        "iterations": int(config.iterations),
        **code.milestone_values(int(config.iterations), config.reference_iterations),
    }
    prefix = settings.prefix(work)
    extra = {
        **{step: tuple(config.train_args) for step in code.train_steps},
        "render": tuple(config.render_args),
    }
    commands = [
        CommandRecord(
            step,
            prefix
            + code.command(
                step,
                argv,
                values,
                suite,
                extra.get(step, ()),
                scene=source.name,
                schedule_lengths=lengths,
                preset_args=(*config.preset_args, *background_args(code, source, suite)),
            ),
            str(checkout),
        )
        for step, argv in code.commands
    ]
    if not mark_finished(work, commands) and work.exists():
        shutil.rmtree(work)
    shutil.rmtree(scene_dir, ignore_errors=True)
    work.mkdir(parents=True, exist_ok=True)
    if (
        write_for_code(code, source, scene_dir, suite, train_split, test_split, resolution)
        != scene_dir
    ):
        raise OfficialRunError(f"{code.name}: the scene was not written to {scene_dir}")
    if config.init_points is not None:
        write_initial_points(
            scene_dir / code.point_cloud, source.split(train_split), config.init_points, seed
        )
    order = Path(code.render_order([record.argv for record in commands]).format_map(values))
    env = dict(code.env)
    if settings.device == "cpu":
        from olatbench.methods.official.cpu_standins import job_environment

        env.update(job_environment(code.name))
    return OfficialRun(
        code=code,
        settings=settings,
        work=work,
        scene_dir=scene_dir,
        model_dir=model_dir,
        commands=commands,
        frame_ids=[frame.frame_id for frame in source.split(test_split)],
        render_order=order,
        values=values,
        colourspace=code.colourspace_for(suite),
        env=env,
    )


def background_args(code: OfficialCode, source: Scene, suite: str) -> tuple[str, ...]:
    """The train flags that put ``source`` on its own background
    (`OfficialCode.white_background_args`): for a scene of no benchmark suite whose declared
    background is white; empty otherwise (black is every code's default, and a benchmark suite keeps
    its scripts' flags)."""
    white = bool(np.all(np.asarray(source.background, dtype=np.float64) >= 1.0))
    return code.white_background_args if white and suite not in SUITES else ()


STEPS_DIR = "steps"  # below work: <step>.json for each command that finished (module docstring)


def step_file(work: Path, step: str) -> Path:
    """Where ``work`` records that the command of ``step`` finished."""
    return work / STEPS_DIR / f"{step}.json"


def mark_finished(work: Path, commands: list[CommandRecord]) -> int:
    """Mark as done (``resumed``, with their recorded wall time) the leading ``commands`` that an
    earlier attempt in ``work`` finished with the same argument lists; returns how many
    (0: start from scratch)."""
    done = 0
    for record in commands:
        try:
            earlier = json.loads(step_file(work, record.step).read_text())
        except (OSError, ValueError):
            break
        if not isinstance(earlier, dict) or earlier.get("argv") != record.argv:
            break
        record.exit_code, record.seconds, record.resumed = (
            0,
            float(earlier.get("seconds") or 0.0),
            True,
        )
        done += 1
    return done


def config_problems(code: OfficialCode, config: OfficialConfig) -> list[str]:
    """What in ``config`` ``code`` cannot do (empty when it can)."""
    problems = []
    try:
        code.milestone_values(int(config.iterations), config.reference_iterations)
    except ValueError as error:
        problems.append(str(error))
    if config.reference_iterations is not None and not code.schedule_flags:
        problems.append(
            f"reference_iterations={config.reference_iterations} is set, but olatbench knows no "
            f"schedule flags of {code.name} to scale; unset it"
        )
    if config.init_points is not None and not code.point_cloud:
        problems.append(
            f"init_points={config.init_points} is set, but {code.name}'s loader reads no initial "
            "point cloud; unset it"
        )
    return problems


def write_initial_points(path: Path, frames: list[Frame], count: int, seed: int) -> Path:
    """Write ``count`` initial points for an official loader to ``path`` (PLY with normals and
    colours, as the 3DGS loaders' ``fetchPly`` reads): drawn like a native method's from ``seed`` in
    the ball fitted to the training ``frames``' cameras (`initial_points`), zero normals, grey (0.5)
    colours — the colour the 3DGS Blender loaders give their random points (``SH2RGB`` of values
    below 1/255)."""
    # these import torch: only for runs that write points
    from olatbench.gaussians.ply import write_ply_points
    from olatbench.methods.initialisation import initial_points

    points = initial_points([frame.camera for frame in frames], count, seed)
    return write_ply_points(
        path, points, colours=np.full_like(points, 0.5), normals=np.zeros_like(points)
    )


def execute(run: OfficialRun, log_path: Path) -> None:
    """Run the commands in order with their output appended to ``log_path``
    (`OfficialRunError` on failure), skipping those an earlier attempt finished (`mark_finished`)
    and recording each that finishes (`step_file`)."""
    minutes = run.settings.timeout_minutes
    for record in run.commands:
        if record.resumed:
            with open(log_path, "a") as log:
                marker = step_file(run.work, record.step)
                log.write(
                    f"{record.step}: finished by an earlier attempt of this job ({marker}), not "
                    "rerun\n"
                )
            continue
        run_command(record, log_path, run.env, None if minutes is None else 60.0 * minutes)
        write_json(
            step_file(run.work, record.step), {"argv": record.argv, "seconds": record.seconds}
        )


def collect(run: OfficialRun) -> dict[str, Path]:
    """``{frame id: its render}``, paired through ``run.render_order`` (`pair_renders`; confirmed by
    the ground truths the script wrote, where it writes them: `check_ground_truths`) and checked to
    exist; `OfficialRunError` listing the missing ones otherwise."""
    renders = pair_renders(run.code, run.render_order, run.frame_ids, run.values)
    check_ground_truths(run.code, run.render_order, run.values)
    missing = [(frame_id, path) for frame_id, path in renders.items() if not path.is_file()]
    if missing:
        shown = "\n".join(f"  {frame_id}: {path}" for frame_id, path in missing[:5])
        folder = missing[0][1].parent
        found = sorted(p.name for p in folder.iterdir())[:10] if folder.is_dir() else []
        raise OfficialRunError(
            f"{run.code.name}: {len(missing)} of {len(renders)} test renders are missing "
            f"(pattern {run.code.renders!r}), e.g.\n{shown}\n{folder} holds: "
            f"{', '.join(found) if found else 'nothing'}"
        )
    return renders
