"""``olatbench view``: serve the interactive relighting viewer for trained jobs
(or record what it shows)."""

from __future__ import annotations

import os
import time
from pathlib import Path

import click

from olatbench.cli.options import (
    checked_suite,
    device_option,
    quiet_option,
    resolved_device,
    show_progress,
    suite_filter_option,
)
from olatbench.datasets.sizes import MAX_SIDE
from olatbench.viewer.environment import DEFAULT_SAMPLES, MAX_SAMPLES, SettingsError, map_menu
from olatbench.viewer.geometry import MAX_RESOLUTION


@click.command("view")
@click.argument("folder", type=click.Path(exists=True, file_okay=False, path_type=Path))
@suite_filter_option
@click.option(
    "--port",
    type=click.IntRange(0, 65535),
    default=8080,
    show_default=True,
    help="Port of the web viewer (0: any free port).",
)
@click.option(
    "--host",
    default="127.0.0.1",
    show_default=True,
    help="Address to listen on (0.0.0.0: every one).",
)
@device_option
@click.option(
    "--max-resolution",
    type=click.IntRange(8, MAX_SIDE),
    default=MAX_RESOLUTION,
    show_default=True,
    help="Renders fill the browser window, their longer side capped at this many pixels.",
)
@click.option(
    "--drag-scale",
    type=click.FloatRange(0.05, 1.0),
    default=0.5,
    show_default=True,
    help="Resolution factor while the camera or light moves (full resolution once still).",
)
@click.option(
    "--envmap",
    "envmaps",
    multiple=True,
    metavar="FILE",
    help="An .exr/.hdr environment map to add to the tab's map menu beside the built-in studio, "
    "sky and furnace (repeatable).",
)
@click.option(
    "--samples",
    type=click.IntRange(1, MAX_SAMPLES),
    default=DEFAULT_SAMPLES,
    show_default=True,
    help="Environment-map mode: the samples K a still view is refined to (the tab can change it).",
)
@click.option(
    "--record",
    nargs=2,
    type=(click.Choice(("light-orbit", "view-orbit")), click.Path(dir_okay=False, path_type=Path)),
    help="Instead of serving: render KIND OUT.mp4 (the sweep of 'olatbench render').",
)
@click.option(
    "--component", default="rgb", show_default=True, help="With --record: the output to record."
)
@click.option(
    "--frames", "count", type=click.IntRange(min=1), help="With --record: spread this many frames."
)
@click.option(
    "--start-frame",
    help="With --record: test frame id whose camera and light start (default: first).",
)
@quiet_option
def view(
    folder,
    suite,
    port,
    host,
    device,
    max_resolution,
    drag_scale,
    envmaps,
    samples,
    record,
    component,
    count,
    start_frame,
    quiet,
) -> None:
    """Open a web viewer on a trained job (or every job of a run folder); a job still training is
    followed, its newest checkpoint shown as the runner writes it.

    Exit code: 1 when no job below FOLDER can be shown (each one's reason is listed), 2 for a usage
    error (FOLDER holds no job.json at all, an unknown suite).

    \b
    Move the light (handle or sliders), orbit the camera, switch outputs (rgb, diffuse, specular,
    sss, shadow, …), snap to a dataset frame to see its ground truth and PSNR. The 'lighting' menu
    switches to an environment map (rotation, exposure, samples K): a few samples while the view
    moves, refined to the K-sample image of 'olatbench render --envmap' while it is still.
    Examples:
      olatbench view runs/mini/ssdgs/default/translucent/seed0
      olatbench view runs/mini --port 8081 --max-resolution 1024
      olatbench view runs/ -s mycaptures          # the jobs of one suite (e.g. of olatbench.toml)
      olatbench view runs/mini/ssdgs/default/translucent/seed0 --envmap room.exr --samples 128
      olatbench view runs/mini/ssdgs/default/translucent/seed0 --record light-orbit orbit.mp4
    """
    # Idle OpenMP threads sleep instead of spinning: on a shared 2-core machine spinning made each
    # render of the native kernels 8x slower with 2 threads (benchmarks/bench_viewer.py,
    # docs/viewer.md). Set before torch loads.
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    device = resolved_device(device)
    from olatbench.bench.restore import RestoreError
    from olatbench.bench.store import in_suite
    from olatbench.viewer.jobs import NoJobFolder, job_folders
    from olatbench.viewer.model import ViewerModel

    suite = checked_suite(suite)
    try:
        maps = map_menu(envmaps)
    except SettingsError as error:  # one line naming the file
        raise click.UsageError(str(error)) from None
    try:
        folders, skipped = job_folders(folder, device)
        folders = [job for job in folders if in_suite(job, suite)]
        if not folders:
            of_suite = f" of suite {suite}" if suite else ""
            raise click.ClickException(
                f"{folder}: no job with a checkpoint{of_suite} in or below it"
            )
        for line in skipped:
            click.echo(f"skipped: {line}", err=True)
        first = ViewerModel.open(folders[0], device)
    # like a folder that does not exist: the argument is wrong (exit 2)
    except NoJobFolder as error:
        raise click.UsageError(str(error)) from None
    except RestoreError as error:
        raise click.ClickException(str(error)) from None
    if record is not None:
        _record(
            first,
            *record,
            component=component,
            count=count,
            start_frame=start_frame,
            progress=show_progress(quiet),
        )
        return
    try:
        from olatbench.viewer.server import ViewerApp

        app = ViewerApp(
            folders,
            first,
            host=host,
            port=port,
            device=device,
            drag_scale=drag_scale,
            max_resolution=max_resolution,
            maps=maps,
            samples=samples,
        ).start()
    except OSError as error:
        raise click.ClickException(
            f"cannot listen on {host}:{port} ({error}); try --port 0"
        ) from None
    click.echo(f"olatbench view: {len(folders)} job(s) at {app.url} (Ctrl-C to stop)")
    try:
        while True:
            time.sleep(1.0)
    except KeyboardInterrupt:
        pass
    finally:
        app.stop()


def _record(
    model,
    kind: str,
    out: Path,
    *,
    component: str,
    count: int | None,
    start_frame: str | None,
    progress: bool,
) -> None:
    from olatbench.reports.jobfolder import JobFolder, JobFolderError
    from olatbench.reports.video import render_sweep

    try:
        result = render_sweep(
            JobFolder.open(model.folder),
            kind,
            out.parent,
            count=count,
            frame_id=start_frame,
            component=component,
            method=model.method,
            video=out,
            progress=progress,
        )
    except (JobFolderError, OSError, ValueError) as error:
        raise click.ClickException(str(error)) from None
    click.echo(
        f"wrote {result.video} ({result.frames} frames, {result.encoder}; frames in "
        f"{result.frames_dir})"
    )
