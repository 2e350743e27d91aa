"""``olatbench run`` and ``olatbench status``: plan, execute and inspect benchmark jobs."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from olatbench.atomic import WriteError
from olatbench.bench.executors import EXECUTORS
from olatbench.bench.plan import OverridesError, PlanError
from olatbench.cli.options import (
    Resolution,
    checked_suite,
    device_option,
    json_option,
    name_list,
    option,
    quiet_option,
    resolved_device,
    show_progress,
    suite_filter_option,
)


def _parse_minutes(value: str) -> int:
    """Minutes from ``90``, ``1:30:00`` (H:MM:SS) or ``2-00:00:00`` (D-HH:MM:SS)."""
    days, _, clock = value.rpartition("-") if "-" in value else ("0", "", value)
    parts = [int(part) for part in clock.split(":")]
    if len(parts) == 1:
        return int(days) * 1440 + parts[0]
    while len(parts) < 3:
        parts.append(0)
    hours, minutes, seconds = parts[:3]
    return int(days) * 1440 + hours * 60 + minutes + (1 if seconds else 0)


def _format_seconds(seconds: float | None) -> str:
    if seconds is None:
        return "—"
    minutes, secs = divmod(round(seconds), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}:{minutes:02d}:{secs:02d}" if hours else f"{minutes}:{secs:02d}"


def _table(rows: list[list[str]], header: list[str]) -> str:
    widths = [max(len(str(row[i])) for row in [header, *rows]) for i in range(len(header))]
    lines = [
        "  ".join(str(cell).ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
        for row in [header, *rows]
    ]
    lines.insert(1, "  ".join("-" * width for width in widths))
    return "\n".join(lines)


def _metric(metrics: dict, key: str) -> str:
    value = metrics.get(key)
    return "—" if value is None else f"{value:.4f}" if key != "psnr" else f"{value:.2f}"


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--method", "-m", required=True, help="Method name (see: olatbench methods list).")
@click.option(
    "--suite", "-s", help="Suite: nrhints, gs3, sssgs, mini, or a [suites.NAME] of olatbench.toml."
)
@click.option(
    "--data",
    "data_paths",
    multiple=True,
    type=click.Path(exists=True, file_okay=False, path_type=Path),
    help="Instead of --suite: a scene folder of your own (NRHints, GS³ or SSS-GS format, detected; "
    "repeatable). Protocol, resolution and iterations are those of the format's suite unless "
    "given; runs go to OUTPUT/data-<format>/...",
)
@click.option(
    "--protocol",
    "protocol_name",
    help="With --data: the metric protocol (default: the format's suite's; "
    "see olatbench metrics list).",
)
@click.option(
    "--scenes", multiple=True, help="Scenes to run (comma-separated or repeated; default: all)."
)
@click.option(
    "--variant",
    "variants",
    multiple=True,
    help="Method preset applied on top of the suite preset, e.g. ablation-A (repeatable).",
)
@click.option(
    "--ablation",
    metavar="GRID",
    help="Expand one of the method's ablation grids (olatbench methods show METHOD lists them); "
    "SSD-GS: components = ablation-A…F, schedule = schedule-H…K, shadow-on-sss = default + "
    "shadow-on-sss.",
)
@click.option("--seeds", default=1, show_default=True, help="Seeds 0…N-1 per scene and variant.")
@click.option(
    "--iterations",
    type=int,
    help="Training iterations (the method scales its schedule); exactly "
    "--set iterations=N: its own folder and report row.",
)
@click.option(
    "--set",
    "overrides",
    multiple=True,
    metavar="KEY=VALUE",
    help="Override one config field of every job (repeatable; checked against the field's type: "
    "true/false, 50, 0.5, [1,1,1], null, text). The overrides join the variant's name, so such "
    "runs get their own folders. Fields: "
    "olatbench methods show METHOD.",
)
@click.option(
    "--code",
    "code_settings",
    multiple=True,
    metavar="KEY=VALUE",
    help="Official implementations (*-official): where the authors' code lives and runs, over "
    "olatbench.toml [official.METHOD] and $OLATBENCH_<METHOD>_<KEY>: checkout=PATH and one of "
    "python=PATH, conda_env=NAME, container='TEMPLATE'; timeout_minutes=N; device=cpu runs the "
    "unmodified code on the CPU with olatbench's stand-ins for its CUDA modules (default cuda) "
    "(repeatable; not part of the job id). See docs/official.md.",
)
@click.option(
    "--resolution",
    type=Resolution(),
    help="Image size N (N×N) or WxH to train and score at (default: the suite's; your own scenes: "
    "their own size). At most the scene's size and with its aspect ratio unless --upscale / "
    "--stretch; a size other than the suite's names the variant (default~resolution=32x32), so it "
    "gets its own folder.",
)
@click.option(
    "--stretch", is_flag=True, help="Allow a --resolution that changes the scene's aspect ratio."
)
@click.option(
    "--upscale", is_flag=True, help="Allow a --resolution larger than the scene's own images."
)
@click.option(
    "--init-points",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="Start the Gaussians at the points of this PLY (world units, the scene's frame) instead "
    "of the method's own initialisation (methods with the init_points capability: ssdgs, gs3, "
    "3dgs). Without it a scene folder's points3d.ply is used when there is one. The file's "
    "content is part of the job id; its name joins the variant label (~init_points=<stem>).",
)
@click.option(
    "--data-root",
    type=click.Path(file_okay=False, path_type=Path),
    help="Folder holding the suite's scene folders (default: $OLATBENCH_DATA; mini: its cache).",
)
@option(
    "-o",
    "--output",
    "out",
    aliases=("--out",),
    default=Path("runs"),
    show_default=True,
    type=click.Path(file_okay=False, path_type=Path),
    help="Output root of the run folders.",
)
@device_option
@click.option(
    "--executor",
    type=click.Choice(EXECUTORS),
    help="inline (this process), local (process pool), slurm (job array via submitit). "
    "Default: inline, or local with --jobs > 1.",
)
@click.option(
    "--jobs",
    "-j",
    "workers",
    default=1,
    show_default=True,
    help="Parallel jobs for the local executor.",
)
@click.option(
    "--dry-run",
    is_flag=True,
    help="Print the job table with each job's state and exit (never generates data).",
)
@click.option(
    "--calibrate",
    is_flag=True,
    help="With --dry-run: time each job configuration not yet timed on this machine (a few "
    "training steps on its own views: seconds to a minute each) and store it, so dry runs print "
    "wall-time estimates.",
)
@click.option(
    "--force",
    is_flag=True,
    help="Rerun jobs from scratch, replacing finished, partial or stale folders.",
)
@click.option(
    "--keep-finished",
    is_flag=True,
    help="Where a folder holds another job than the plan's (its config, data, point cloud or code "
    "changed since): keep it as it is when that job finished, and replace it (rerun) only when it "
    "did not; --force replaces them all.",
)
@click.option(
    "--no-reuse",
    "no_reuse",
    is_flag=True,
    help="Train every job even when a finished job of another variant name is the same experiment "
    "(same resolved config, data, code and seed, e.g. SSD-GS's ablation-D, schedule-I and "
    "default); by default such a job evaluates that job's model instead of training again.",
)
@click.option(
    "--checkpoint-every",
    type=int,
    help="Checkpoint every N steps (default: iterations/10; also every 10 minutes).",
)
@click.option(
    "--save-components",
    is_flag=True,
    help="Also save render components (diffuse, shadow, ...) of the test split.",
)
@click.option(
    "--evaluate",
    "evaluations",
    multiple=True,
    type=click.Choice(("novel-lights",)),
    help="Also score each job under novel illumination: its test cameras rendered under every "
    "condition of the scene's novel_lights/ ground truth (olatbench-v1-novel-lights, into "
    "results.json's novel_lights). Finished jobs without these scores get them from their final "
    "checkpoint, without retraining. docs/relighting.md.",
)
@click.option(
    "--novel-samples",
    type=click.IntRange(min=1),
    help="With --evaluate novel-lights: sample environment maps in this many directions (default: "
    "each lighting file's count; area lights keep the ground truth's points).",
)
@click.option(
    "--novel-views",
    type=click.IntRange(min=1),
    help="With --evaluate novel-lights: score only the first N test frames of each condition "
    "(default: all).",
)
@click.option("--slurm-partition", help="Slurm partition.")
@click.option(
    "--slurm-time",
    default="24:00:00",
    show_default=True,
    help="Wall-clock limit per task (minutes or [D-]H:MM:SS).",
)
@click.option("--slurm-gpus", default=0, show_default=True, help="GPUs per task.")
@click.option("--slurm-cpus", default=4, show_default=True, help="CPUs per task.")
@click.option(
    "--slurm-array-parallelism", default=64, show_default=True, help="Tasks running at once."
)
@click.option(
    "--wait/--no-wait",
    default=False,
    show_default=True,
    help="With --executor slurm: wait for the array and print the summary.",
)
@quiet_option
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="With --dry-run: print the plan as JSON (one object per job).",
)
def run(
    method,
    suite,
    data_paths,
    protocol_name,
    scenes,
    variants,
    ablation,
    seeds,
    iterations,
    overrides,
    code_settings,
    resolution,
    stretch,
    upscale,
    init_points,
    data_root,
    out,
    device,
    executor,
    workers,
    dry_run,
    calibrate,
    force,
    keep_finished,
    no_reuse,
    checkpoint_every,
    save_components,
    evaluations,
    novel_samples,
    novel_views,
    slurm_partition,
    slurm_time,
    slurm_gpus,
    slurm_cpus,
    slurm_array_parallelism,
    wait,
    quiet,
    as_json,
) -> None:
    """Train and evaluate METHOD on every scene of SUITE (or on your own scene folders, --data);
    rerunning skips finished jobs and resumes interrupted ones from their last checkpoint.

    Jobs are method × scene × variant × seed. Each writes to
    OUTPUT/<suite>/<method>/<variant>/<scene>/seed<k>/ (results.json, renders, checkpoints, logs).
    Exit code: 0 when every job is done; 1 when any failed (the count is printed) or the output
    folder cannot be written; 2 for a usage error (including a --set value out of its field's
    range); 3 when none failed but some are running in another process (rerun once they finish).
    With --executor slurm --no-wait: 0 once submitted. A finished job whose results.json or job.json
    is damaged is re-evaluated from its final checkpoint, the damaged file kept as <name>.damaged.
    Folders holding a job planned with other inputs (stale) stop the run unless --keep-finished
    (keep the finished ones, rerun the rest) or --force (rerun them all).

    \b
    Examples:
      olatbench run --method ssdgs --suite mini
      olatbench run -m ssdgs --data captures/cup   # your own scene; --dry-run shows its presets
      olatbench run -m 3dgs --data captures/cup --data captures/mug --iterations 30000 \\
          --resolution 256
      olatbench run -m ssdgs -s nrhints --scenes Pixiu,Fish --data-root /data/nrhints
      olatbench run -m ssdgs -s nrhints --scenes Pixiu --ablation components --dry-run
      olatbench run -m ssdgs -s gs3 --scenes Lego --data-root /data/gs3 --dry-run --calibrate
      olatbench run -m ssdgs -s mini --scenes translucent --set shadow_mode=density --set num_asg=8
      olatbench run -m ssdgs -s mini --evaluate novel-lights   # + novel-light scores
      olatbench run -m 3dgs --data captures/cup --init-points captures/cup/sparse.ply
      olatbench run -m ssdgs -s gs3 --seeds 3 --executor slurm --slurm-partition gpu --slurm-gpus 1
      olatbench run -m gs3-official -s gs3 --code checkout=~/src/gs-relight --code conda_env=gs3
      olatbench run -m ssdgs-official -s mini --code checkout=~/SSD-GS \\
          --code python=~/venv/bin/python --code device=cpu
    """
    from olatbench.bench import session
    from olatbench.bench.executors import SlurmOptions, Terminated
    from olatbench.bench.plan import PlanOptions, make_plan, parse_overrides
    from olatbench.bench.reuse import reuse_notes
    from olatbench.datasets.errors import DatasetError
    from olatbench.methods.official.settings import SettingsError, parse_code_options
    from olatbench.methods.registry import canonical_method_name

    try:
        # -m SSDGS runs ssdgs; -m ssgds: "did you mean 'ssdgs'?"
        method = canonical_method_name(method)
    except KeyError as error:
        raise click.UsageError(f"{error.args[0]}. See: olatbench methods list") from None
    progress = show_progress(quiet or as_json)
    if as_json and not dry_run:
        raise click.UsageError("--json goes with --dry-run")
    if executor is None:
        executor = "local" if workers > 1 else "inline"
    if calibrate and not dry_run:
        raise click.UsageError("--calibrate goes with --dry-run")
    try:
        code = parse_code_options(code_settings, method)
    except SettingsError as error:
        raise click.UsageError(str(error)) from None
    unknown = sorted(set(code) - {method})
    if unknown:
        raise click.UsageError(f"--code names {', '.join(unknown)}, but this run is of {method}")
    # a dry run leaves "auto" unresolved (the device enters no job id, and resolving it would import
    # torch; a calibration resolves it in plan_estimates, which stores the name for later dry runs);
    # a run resolves and tries it here, before any job starts (a device this machine lacks is a
    # usage error), except a named device of Slurm jobs, which run on other machines
    remote = executor == "slurm" and device != "auto"
    novel = _novel_lights_options(evaluations, novel_samples, novel_views)
    options = PlanOptions(
        device=device if dry_run or remote else resolved_device(device),
        checkpoint_every=checkpoint_every,
        save_components=save_components,
        reuse=not no_reuse,
        code=code.get(method, {}),
        novel_lights=None if novel is None else novel.to_json(),
    )
    try:
        jobs = [
            job
            for plan_suite in _suites(suite, data_paths, protocol_name, data_root)
            for job in make_plan(
                method,
                plan_suite,
                out,
                scenes=name_list(scenes, "--scenes") or (),
                variants=name_list(variants, "--variant") or (),
                ablation=ablation,
                seeds=seeds,
                iterations=iterations,
                resolution=resolution,
                data_root=data_root,
                options=options,
                generate=not dry_run or calibrate,
                progress=progress,
                overrides=parse_overrides(overrides),
                stretch=stretch,
                upscale=upscale,
                init_points=init_points,
            )
        ]
    except OverridesError as error:  # a usage error (exit 2), naming the field
        raise click.UsageError(str(error)) from None
    # what was asked cannot be planned
    except (PlanError, DatasetError, KeyError, FileNotFoundError) as error:
        raise click.UsageError(
            str(error.args[0] if isinstance(error, KeyError) else error)
        ) from None

    if novel is not None:
        _check_novel_lights(jobs)
    states = session.job_states(jobs)
    if dry_run:
        from olatbench.bench.estimate import plan_estimates

        try:
            estimates = plan_estimates(jobs, measure=calibrate, progress=progress)
        except ValueError as error:
            raise click.ClickException(str(error)) from None
        reuse = reuse_notes(jobs) if not no_reuse else [None] * len(jobs)
        estimates = [
            0.0
            if note and seconds is not None and state.state not in ("done", "running")
            else seconds
            for note, state, seconds in zip(reuse, states, estimates, strict=True)
        ]
        if as_json:
            click.echo(json.dumps(plan_json(jobs, states, out, estimates, reuse), indent=2))
        else:
            _print_plan(jobs, states, out, estimates, reuse)
        return

    try:
        decided = session.triage(jobs, states, force=force, keep_finished=keep_finished)
    except session.StaleFoldersError as error:
        raise click.UsageError(str(error)) from None
    if decided.kept:
        kept = decided.kept
        click.echo(
            f"kept {len(kept)} finished job(s) planned with other inputs, as they are (--force "
            "retrains them): "
            f"{', '.join(job.folder for job in kept[:5])}{' …' if len(kept) > 5 else ''}",
            err=True,
        )
    try:
        to_run = session.prepare(decided, reuse=not no_reuse)
    except OSError as error:  # a read-only or full output folder: nothing has run
        raise click.ClickException(
            f"{error if isinstance(error, WriteError) else _os_error_line(error)}; "
            f"the output folder {out} must be writable (choose another with --output)"
        ) from None
    busy = f", {len(decided.running)} running in another process" if decided.running else ""
    repaired = (
        f" ({decided.damaged} damaged: re-evaluated, the damaged files kept as *.damaged)"
        if decided.damaged
        else ""
    )
    click.echo(
        f"{len(jobs)} job(s): {len(decided.skipped)} already done{busy}, {len(to_run)} to "
        f"run{repaired} ({executor}, device {options.device}) -> {out}",
        err=True,
    )
    if novel is not None:
        _add_novel_lights(decided.skipped, novel, progress)
    if not to_run:
        _print_summary(jobs, out)
        _exit_with(session.RunSummary([], len(decided.running)))

    def report(outcome) -> None:
        from olatbench.progress import progress_write

        if outcome.status == "failed":
            where = f" (see {Path(outcome.folder) / 'error.txt'})" if outcome.recorded else ""
            progress_write(f"FAILED {outcome.label}: {outcome.error}{where}")
        elif outcome.status == "skipped":
            progress_write(f"skipped {outcome.label}: {outcome.error}")

    def submitted(tasks: list) -> None:
        click.echo(
            f"submitted {len(tasks)} task(s) as array {tasks[0].job_id.split('_')[0]}; "
            f"follow with: olatbench status {out}",
            err=True,
        )

    slurm = SlurmOptions(
        partition=slurm_partition,
        time_minutes=_parse_minutes(slurm_time),
        gpus=slurm_gpus,
        cpus=slurm_cpus,
        array_parallelism=slurm_array_parallelism,
    )
    try:
        outcomes, _ = session.execute(
            to_run,
            out,
            session.Executor(executor, workers, slurm, wait),
            progress,
            report,
            submitted,
        )
    # Ctrl-C, or SIGTERM to the local executor (its workers are stopped)
    except KeyboardInterrupt as interrupted:
        click.echo(
            f"\nInterrupted. Rerun the same command to resume from the last checkpoints "
            f"(olatbench status {out} shows where each job stands).",
            err=True,
        )
        sys.exit(
            session.EXIT_TERMINATED
            if isinstance(interrupted, Terminated)
            else session.EXIT_INTERRUPTED
        )
    if executor == "slurm" and not wait:
        return
    _print_summary(jobs, out)
    _exit_with(session.RunSummary(outcomes, len(decided.running)))


def _novel_lights_options(evaluations, samples: int | None, views: int | None):
    """`olatbench.bench.novel_lights.NovelLightsOptions` of ``--evaluate novel-lights``
    (None when not asked); ``--novel-samples`` / ``--novel-views`` without it are a usage error."""
    if "novel-lights" not in evaluations:
        if samples is not None or views is not None:
            raise click.UsageError(
                "--novel-samples and --novel-views go with --evaluate novel-lights"
            )
        return None
    from olatbench.bench.novel_lights import NovelLightsOptions

    return NovelLightsOptions(samples=samples, views=views)


def _check_novel_lights(jobs) -> None:
    """Before anything runs: every job can be scored under novel illumination (a native method,
    whose render ``olatbench.bench.relight`` sums over lights, and a scene with novel-light ground
    truth); a usage error naming the job or the folder otherwise."""
    from olatbench.datasets.errors import DatasetError
    from olatbench.datasets.novel_lights import condition_names

    for job in jobs:
        if job.official is not None:
            raise click.UsageError(
                f"--evaluate novel-lights: {job.method} runs the authors' code, which olatbench "
                "cannot render under other lights; leave it out for this method"
            )
    for scene_path in dict.fromkeys(job.scene_path for job in jobs):
        try:
            if not condition_names(scene_path):
                raise DatasetError(
                    "holds no condition (<condition>/lighting.json)",
                    path=Path(scene_path) / "novel_lights",
                )
        except DatasetError as error:
            raise click.UsageError(f"--evaluate novel-lights: {error}") from None


def _add_novel_lights(jobs, options, progress: bool) -> None:
    """Score the finished jobs that have no novel-light scores (of this protocol version and these
    options) from their final checkpoints; a job that cannot be rebuilt or relit is named on stderr
    and the others go on."""
    from olatbench.bench.novel_lights import NovelLightsError, add_novel_lights, has_novel_lights
    from olatbench.bench.relight import RelightError
    from olatbench.bench.restore import RestoreError
    from olatbench.bench.results import ResultsError, read_results
    from olatbench.bench.store import RESULTS_FILE
    from olatbench.datasets.errors import DatasetError

    todo = [
        job
        for job in jobs
        if not has_novel_lights(read_results(Path(job.folder) / RESULTS_FILE), options)
    ]
    if todo:
        click.echo(
            f"scoring {len(todo)} finished job(s) under novel illumination from their final "
            "checkpoints",
            err=True,
        )
    for job in todo:
        try:
            add_novel_lights(job.folder, options, device=job.device, progress=progress)
        except (NovelLightsError, RestoreError, RelightError, ResultsError, DatasetError) as error:
            click.echo(f"novel lights not scored for {job.label}: {error}", err=True)


def _exit_with(summary) -> None:
    """Exit with `run`'s documented code (`olatbench.bench.session.RunSummary.exit_code`), saying
    why when it is not 0: the failed jobs' count, or the jobs left to another process."""
    from olatbench.bench import session

    if summary.exit_code == session.EXIT_FAILED:
        click.echo(
            f"{summary.failed} job(s) failed; fix the cause (error.txt in each folder) and rerun "
            "the same command to retry them.",
            err=True,
        )
    elif summary.exit_code == session.EXIT_RUNNING_ELSEWHERE:
        click.echo(
            f"{summary.elsewhere} job(s) are running in another process; rerun the same command "
            "once they finish to collect them (olatbench status shows them).",
            err=True,
        )
    sys.exit(summary.exit_code)


def _os_error_line(error: OSError) -> str:
    """One line for a file-system error: the file and the reason."""
    return (
        f"{error.filename}: {error.strerror}" if error.filename and error.strerror else str(error)
    )


def _suites(
    suite: str | None, data_paths: tuple[Path, ...], protocol: str | None, data_root: Path | None
) -> list:
    """The suites a run plans: ``--suite`` (built-in or olatbench.toml), or one ``data-<format>``
    suite per format among the ``--data`` folders (`olatbench.datasets.suites.data_suites`), with
    ``--protocol`` when given."""
    import dataclasses

    from olatbench.datasets.suites import data_suites, get_suite

    if (suite is None) == (not data_paths):
        raise click.UsageError(
            "give --suite NAME or --data SCENE_FOLDER (not both), e.g. olatbench run -m 3dgs "
            "--data captures/cup"
        )
    if suite is not None:
        if protocol is not None:
            raise click.UsageError(
                "--protocol goes with --data (a suite names its protocol; a user suite in "
                "olatbench.toml may set protocol = ...)"
            )
        return [get_suite(suite)]
    if data_root is not None:
        raise click.UsageError("--data names each scene folder; --data-root is for --suite")
    if protocol is not None:
        from olatbench.metrics.protocols import get_protocol

        try:
            get_protocol(protocol)
        except ValueError as error:
            raise click.UsageError(str(error)) from None
    return [
        dataclasses.replace(found, protocol=protocol or found.protocol)
        for found in data_suites(data_paths)
    ]


def _state_text(state) -> str:
    return state.state if state.state != "absent" else "pending"


def plan_json(
    jobs, states, out: Path, estimates: list[float | None], reuse: list[str | None]
) -> list[dict]:
    """The dry run's table as data: one object per job, with its resolved config."""
    return [
        {
            "index": index,
            "id": job.id or None,
            "suite": job.suite,
            "method": job.method,
            "variant": job.variant,
            "scene": job.scene,
            "seed": job.seed,
            "iterations": job.iterations,
            "state": _state_text(state),
            "step": state.step,
            "train_seconds_estimate": seconds,
            "reuse": note,
            "resolution": list(job.resolution) if job.resolution else "native",
            "frame": job.frame,
            "folder": str(Path(job.folder).relative_to(out)),
            "config": job.config,
            "sources": job.sources,
            "derived": {
                name: {"value": job.config.get(name), "why": why}
                for name, why in job.derived.items()
            },
        }
        for index, (job, state, seconds, note) in enumerate(
            zip(jobs, states, estimates, reuse, strict=True)
        )
    ]


def _print_plan(
    jobs, states, out: Path, estimates: list[float | None], reuse: list[str | None]
) -> None:
    from olatbench.bench.estimate import DAY_SECONDS, format_duration

    rows = []
    for index, (job, state, seconds, note) in enumerate(
        zip(jobs, states, estimates, reuse, strict=True)
    ):
        status = _state_text(state)
        if state.state == "partial":
            status = f"partial ({state.step}/{state.iterations})"
        elif note and state.state in ("pending", "absent"):
            status = f"pending ({note})"
        size = "native" if job.resolution is None else f"{job.resolution[0]}x{job.resolution[1]}"
        rows.append(
            [
                str(index),
                job.suite,
                job.method,
                job.variant,
                job.scene,
                str(job.seed),
                str(job.iterations),
                size,
                "?" if seconds is None else format_duration(seconds),
                job.id or "(no data yet)",
                status,
                str(Path(job.folder).relative_to(out)),
            ]
        )
    click.echo(
        _table(
            rows,
            [
                "#",
                "suite",
                "method",
                "variant",
                "scene",
                "seed",
                "iters",
                "size",
                "train (est.)",
                "id",
                "state",
                "folder",
            ],
        )
    )
    _print_sources(jobs)
    _print_derived(jobs)
    note = "" if all(job.id for job in jobs) else "; ids are computed once the data exists"
    click.echo(f"{len(jobs)} job(s){note}.")
    known = [seconds for seconds in estimates if seconds is not None]
    if len(known) < len(jobs):
        click.echo(
            "Training-time estimates: add --calibrate to time the untimed configurations on this "
            "machine."
        )
    if known:
        click.echo(
            f"Estimated training time on this machine: {format_duration(sum(known))} in all (one "
            "job at a time; training only)."
        )
        slow = [
            job.label
            for job, seconds in zip(jobs, estimates, strict=True)
            if seconds and seconds > DAY_SECONDS
        ]
        if sum(known) > DAY_SECONDS:
            click.echo(
                f"WARNING: this plan would take more than a day here ({len(slow)} job(s) alone "
                "do); see docs/runner.md 'Paper scale' for what a GPU or more cores change.",
                err=True,
            )


#: What the dry run says of each frame a job may train in (`Suite.frame`).
FRAME_NOTES = {
    "fitted": "the canonical frame fitted to the training cameras (a suite in olatbench.toml may "
    'set frame = "dataset" to keep the data\'s own)',
    "dataset": "the data's own world frame",
}


def _print_sources(jobs) -> None:
    """For each method and variant of the plan, once: where its config values came from
    (source: fields), those left at the config's defaults counted; --json gives every field's
    source."""
    from olatbench.methods.resolve import DEFAULT_SOURCE

    shown = set()
    for job in jobs:
        key = (job.method, job.suite, job.variant, tuple(sorted(job.sources.items())))
        if not job.sources or key in shown:
            continue
        shown.add(key)
        by_source: dict[str, list[str]] = {}
        for name, source in job.sources.items():
            by_source.setdefault(source, []).append(name)
        defaults = len(by_source.pop(DEFAULT_SOURCE, []))
        click.echo(
            f"{job.method} {job.variant} on {job.suite}: config from "
            + "; ".join(f"{source}: {', '.join(names)}" for source, names in by_source.items())
            + f"; {defaults} field(s) at their defaults (olatbench methods show {job.method} "
            f"--suite {job.suite} --variant VARIANT)"
        )


def _print_derived(jobs) -> None:
    """For each scene of no suite, once: the values its preset derived from it and why
    (field: value: reason); a variant or --set given on top still wins, as the config column of
    --json shows."""
    shown = set()
    for job in jobs:
        if not job.derived or (job.method, job.scene, job.variant) in shown:
            continue
        shown.add((job.method, job.scene, job.variant))
        click.echo(
            f"{job.method} on {job.scene} ({job.variant}): preset derived from the scene "
            "(docs/own-data.md):"
        )
        for name, why in job.derived.items():
            click.echo(f"  {name} = {json.dumps(job.config.get(name))}: {why}")
        click.echo(f"  frame: {FRAME_NOTES.get(job.frame, job.frame)}")
        click.echo(
            f"  the rest as in the method's scene recipe (olatbench methods show {job.method} "
            f"--data {job.scene_path})"
        )


def _print_summary(jobs, out: Path) -> None:
    """One line per job of the plan, read back from the folders (so skipped jobs appear too)."""
    from olatbench.bench.results import ResultsError, read_results
    from olatbench.bench.store import RESULTS_FILE

    rows = []
    for job in jobs:
        path = Path(job.folder) / RESULTS_FILE
        try:
            results = read_results(path)
        except ResultsError:
            rows.append(
                [job.scene, job.variant, str(job.seed), "not run", "—", "—", "—", "—", "—", "—"]
            )
            continue
        test = results["metrics"].get(job.test_split, {}).get("mean", {})
        timing = results.get("timing", {})
        fps = timing.get("render_fps")
        rows.append(
            [
                job.scene,
                job.variant,
                str(job.seed),
                results["status"],
                str(results.get("model", {}).get("iterations", "—")),
                _format_seconds(timing.get("train_seconds")),
                "—" if fps is None else f"{fps:.1f}",
                _metric(test, "psnr"),
                _metric(test, "ssim"),
                _metric(test, "lpips"),
            ]
        )
    click.echo(
        _table(
            rows,
            [
                "scene",
                "variant",
                "seed",
                "status",
                "iters",
                "train",
                "fps",
                "test PSNR",
                "SSIM",
                "LPIPS",
            ],
        )
    )


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument(
    "runs", type=click.Path(exists=True, file_okay=False, path_type=Path), default=Path("runs")
)
@suite_filter_option
@json_option
def status(runs: Path, suite: str | None, as_json: bool) -> None:
    """Show the state of every job below RUNS: done, failed, partial (last checkpoint step),
    pending, running (in another process) or damaged (an unreadable job.json or results.json; the
    line below the table says how to repair it), and the warnings of a run that went wrong while
    training (its Gaussian count collapsed, or its training PSNR stayed below an image of the
    background alone; a line below the table each, with the likely cause). Only reads, so a
    read-only run folder can be inspected.

    Exit code: 0 when the states are shown (whatever they are); 2 for a usage error: an unknown
    suite, or RUNS holds no job folder (of the suite given with -s), as when it does not exist.

    \b
    Example:
      olatbench status runs/
      olatbench status runs/ -s mini    # only the mini suite's jobs
      olatbench status runs/ --json     # one object per job folder
    """
    from collections import Counter

    from olatbench.bench.store import in_suite, scan_runs

    suite = checked_suite(suite)
    states = [state for state in scan_runs(runs) if in_suite(state.folder, suite)]
    if not states:
        from olatbench.datasets.suites import DATA_SUITE_PREFIX

        source = (
            "--data SCENE_FOLDER"
            if suite is not None and suite.startswith(DATA_SUITE_PREFIX)
            else f"--suite {suite or 'mini'}"
        )  # data-<format> suites are made by run --data
        raise click.UsageError(
            f"no job folders (job.json){'' if suite is None else f' of suite {suite}'} below "
            f"{runs}; start one with: olatbench run --method ssdgs {source} --output {runs}"
        )
    if as_json:
        click.echo(
            json.dumps(
                [
                    {
                        "job": str(state.folder.relative_to(runs)),
                        "state": state.state,
                        "id": state.job_id,
                        "step": state.step,
                        "iterations": state.iterations,
                        "message": state.message,
                        "warnings": list(state.warnings),
                    }
                    for state in states
                ],
                indent=2,
            )
        )
        return
    rows = []
    for state in states:
        step = (
            "—"
            if state.step is None
            else f"{state.step}/{'?' if state.iterations is None else state.iterations}"
        )
        note = state.message or (
            f"WARNING: {state.warnings[0].partition(':')[0]}" if state.warnings else ""
        )
        rows.append([str(state.folder.relative_to(runs)), state.state, step, note[:80]])
    click.echo(_table(rows, ["job", "state", "step", "note"]))
    counts = Counter(state.state for state in states)
    click.echo(", ".join(f"{count} {name}" for name, count in sorted(counts.items())))
    for state in states:
        # the whole message: what is damaged and the command that repairs it
        if state.state == "damaged":
            click.echo(f"damaged {state.folder.relative_to(runs)}: {state.message}")
        # a ruined run says so, with the likely cause (olatbench.bench.health)
        for warning in state.warnings:
            click.echo(f"WARNING {state.folder.relative_to(runs)}: {warning}")
