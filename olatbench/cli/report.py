"""``olatbench report`` (the paper's tables from results.json files) and ``olatbench render``
(sweeps)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import click

from olatbench.atomic import WriteError, write_text
from olatbench.cli.options import (
    Resolution,
    checked_suite,
    device_option,
    name_list,
    quiet_option,
    resolved_device,
    show_progress,
)

LAYOUTS = ("scenes", "overview", "ablation")
# olatbench.reports.figures.FIGURE_FORMATS (not imported: matplotlib)
FIGURE_FILE_FORMATS = ("png", "svg", "pdf")
FIGURE_CHOICES = ("embed", *FIGURE_FILE_FORMATS, "none")


def _emit(text: str, output: str | None) -> None:
    if output is None:
        click.echo(text, nl=False)
        return
    try:
        write_text(output, text)
    # read-only folder, full disk: one line, the old file (if any) untouched
    except WriteError as error:
        raise click.ClickException(f"{error}; choose another -o") from None
    click.echo(f"wrote {output}", err=True)


@click.command("report")
@click.argument("runs", nargs=-1, type=click.Path(exists=True, path_type=Path))
@click.option(
    "--suite",
    "-s",
    help="Only runs of this suite (nrhints, gs3, sssgs, mini, a [suites.NAME] of "
    "olatbench.toml, data-<format>); names its scenes.",
)
@click.option(
    "--methods", help="Comma-separated methods (or method/variant) to include; default all."
)
@click.option(
    "--metrics", default="psnr,ssim,lpips", show_default=True, help="Comma-separated metric blocks."
)
@click.option("--splits", default="train,test", show_default=True, help="Comma-separated splits.")
@click.option(
    "--layout",
    "layouts",
    type=click.Choice(LAYOUTS),
    multiple=True,
    help="Table layout(s): per-scene (Table 1), overview (mean ± std, FPS, time, device) or "
    "ablation grid (A–F, H–K). Repeatable; default scenes.",
)
@click.option(
    "--average/--no-average", default=False, help="Add a scene-average column (scenes layout)."
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(("latex", "markdown", "csv", "html")),
    help="Output format; default from -o's suffix, else markdown. csv is data, not the table: one "
    "row per job × split × metric with the job's identity (with --published-only: the paper's "
    "numbers).",
)
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the results as JSON: one object per job × split × metric, numbers as numbers, with "
    "the job's identity, seed and protocol.",
)
@click.option(
    "-o", "--output", type=click.Path(dir_okay=False), help="Write to this file instead of stdout."
)
@click.option(
    "--standalone",
    is_flag=True,
    help="LaTeX: a complete document that compiles with pdflatex and texlive-latex-recommended "
    "alone (no multirow or diagbox). Without it: the paper's table code, opened by a comment "
    "naming the packages its preamble needs.",
)
@click.option(
    "--fit",
    is_flag=True,
    help="LaTeX: shrink a table wider than the text to the line width (default: every table at its "
    "natural width, its caption at the document's size).",
)
@click.option(
    "--booktabs",
    is_flag=True,
    help=(
        "LaTeX: booktabs rules for every table (default: \\hline, and booktabs where the paper "
        "uses it)."
    ),
)
@click.option(
    "--colours",
    help='Best;second colours as rgb in [0,1], default "1,0.8,0.8;1,0.9,0.8" (the paper).',
)
@click.option(
    "--published", is_flag=True, help="Put the paper's numbers (and a Δ row) beside matching runs."
)
@click.option(
    "--versus",
    metavar="ROW",
    help="Scenes layout: beneath every other row a Δ row (that row − ROW), each cell marked s "
    "where the difference exceeds 2 × the pooled sample std over seeds, n where it is within seed "
    "noise. ROW: a row's label as printed, or method[/variant] when one row has it.",
)
@click.option(
    "--published-only", is_flag=True, help="Regenerate the paper's tables from its numbers alone."
)
@click.option(
    "--table",
    "paper_tables",
    multiple=True,
    type=click.Choice(
        (
            "real",
            "gs3",
            "sssgs",
            "sssgs-overview",
            "ablation",
            "ablation-scenes",
            "shadow-on-sss",
            "relighting-baselines",
        )
    ),
    help="With --published-only: which paper table(s); default all.",
)
@click.option(
    "--seeds",
    type=click.Choice(("mean", "all")),
    default="mean",
    show_default=True,
    help="Average seeds into one row, or show every seed as its own row.",
)
@click.option(
    "--figures",
    "figure_format",
    type=click.Choice(FIGURE_CHOICES),
    default="embed",
    show_default=True,
    help="HTML: embed comparison grids, decompositions and training curves in the page (embed); "
    "png, svg or pdf: also write each as a file in <OUTPUT name>_figures/ beside the page (PNG at "
    "300 dpi; SVG and PDF vector), linked from its caption; none: no figures.",
)
@click.option(
    "--frames",
    "frame_ids",
    help="HTML figures: comma-separated test frame ids (default: the first).",
)
def report(
    runs,
    suite,
    methods,
    metrics,
    splits,
    layouts,
    average,
    fmt,
    as_json,
    output,
    standalone,
    fit,
    booktabs,
    colours,
    published,
    versus,
    published_only,
    paper_tables,
    seeds,
    figure_format,
    frame_ids,
) -> None:
    """Build the paper's tables (and an HTML page with figures) from results.json files below RUNS
    (default: ./runs). A cell averages only jobs identical but for the seed; jobs that differ get
    their own rows. Rows, figure keys and JSON records name an experiment by one label:
    method/variant and, in parentheses, every setting that differs from the suite's defaults
    (e.g. ssdgs/mini (iterations=200)). Failed and unfinished jobs (running, interrupted, planned)
    are named under each table with their cell and why.

    A results.json that cannot be read is named on stderr and left out; the others still make the
    tables. Exit code: 0 when the report was written, 1 when there is nothing readable to report or
    the output cannot be written (one line says why), 2 for a usage error (RUNS holds neither a job
    folder nor a results.json, nothing matches the selection, an unknown suite, ...).

    \b
    Examples:
      olatbench report runs/ --suite nrhints --average
      olatbench report runs/ --json > results.json        # every number, with its job's identity
      olatbench report runs/ -o results.csv               # the same as tidy CSV
      olatbench report runs/ --suite nrhints --published -o table.tex --standalone
      olatbench report runs/ --suite mini --methods ssdgs --versus ssdgs/mini  # Δ, seed noise
      olatbench report runs/ --suite nrhints -o table.tex --fit  # paper code, at most the line wide
      olatbench report runs/ --layout ablation --format markdown
      olatbench report runs/ --suite sssgs --layout overview -o report.html
      olatbench report runs/ --suite mini -o report.html --figures pdf   # + report_figures/*.pdf
      olatbench report --published-only --table real -o table1a.tex
    """
    from olatbench.bench.results import ResultsError
    from olatbench.reports.output import format_for, parse_colours, render_tables
    from olatbench.reports.published import PublishedError
    from olatbench.reports.runs_tables import ReportError

    suite = checked_suite(suite)
    if as_json and fmt not in (None, "json"):
        raise click.UsageError("--json prints JSON; leave out --format")
    try:
        fmt = format_for(output, fmt)
        palette = parse_colours(colours)
        # None: each table's own (the paper's, for --published-only)
        rules = "booktabs" if booktabs else None
        if published_only:
            from olatbench.reports.paper import paper_table
            from olatbench.reports.published import PAPER_TABLES
            from olatbench.reports.tidy import published_csv

            if as_json:
                raise click.UsageError(
                    "--json is for runs; --published-only --format csv gives the paper's numbers"
                )
            names = paper_tables or PAPER_TABLES
            text = (
                published_csv(names)
                if fmt == "csv"
                else render_tables(
                    [paper_table(name) for name in names],
                    fmt,
                    standalone=standalone,
                    colours=palette,
                    rules=rules,
                    title="SSD-GS (ICLR 2026): published tables",
                    fit=fit,
                )
            )
            _emit(text, output)
            return
        if not runs and Path("runs").is_dir():
            runs = (Path("runs"),)
        if not runs:
            raise click.UsageError(
                "give a runs folder (or results.json files), or use --published-only; e.g. "
                "olatbench report runs/ --suite mini"
            )
        if versus is not None and (
            as_json or fmt == "csv" or "scenes" not in (layouts or ("scenes",))
        ):
            raise click.UsageError("--versus adds Δ rows to the scenes layout's table")
        if as_json or fmt == "csv":
            text = _report_data(
                runs,
                suite,
                name_list(methods, "--methods"),
                name_list(metrics, "--metrics"),
                name_list(splits, "--splits"),
                as_json,
            )
        else:
            if figure_format in FIGURE_FILE_FORMATS and (fmt != "html" or output is None):
                raise click.UsageError(
                    f"--figures {figure_format} writes the figures beside an HTML page: add "
                    "-o report.html"
                )
            text = _report_runs(
                runs,
                suite,
                name_list(methods, "--methods"),
                name_list(metrics, "--metrics"),
                name_list(splits, "--splits"),
                layouts or ("scenes",),
                average,
                fmt,
                standalone,
                palette,
                rules,
                published,
                seeds,
                figure_format,
                name_list(frame_ids, "--frames") or [],
                output,
                fit,
                versus,
            )
    except ResultsError as error:
        raise click.ClickException(
            f"{error}\n'olatbench status RUNS' shows which jobs finished."
        ) from None
    # the figure files (--figures png|svg|pdf) cannot be written: one line
    except WriteError as error:
        raise click.ClickException(f"{error}; choose another -o") from None
    except (ReportError, PublishedError, ValueError, FileNotFoundError) as error:
        raise click.UsageError(
            f"{error}\n'olatbench status RUNS' shows which jobs finished."
        ) from None
    _emit(text, output)


def _collect(runs):
    """The results below ``runs`` (`olatbench.reports.collect.collect`), each unreadable
    results.json named on stderr; a `ResultsError` (exit 1: nothing to report) when there is none or
    none is readable."""
    from olatbench.bench.results import ResultsError
    from olatbench.reports.collect import collect

    unreadable: list[str] = []
    frame = collect(runs, unreadable)
    for message in unreadable:
        click.echo(f"skipped (unreadable): {message}", err=True)
    if frame.empty and unreadable:
        raise ResultsError(
            f"no readable results.json below {', '.join(map(str, runs))} ({len(unreadable)} "
            "unreadable, listed above); 'olatbench run' with the same options re-evaluates a "
            "finished job whose results.json is damaged"
        )
    if frame.empty and not any(_holds_jobs(Path(path)) for path in runs):
        raise click.UsageError(
            f"no job folder and no results.json below {', '.join(map(str, runs))}; give the "
            "--output folder of 'olatbench run', or run 'olatbench run --method ssdgs --suite "
            "mini' first"
        )
    if frame.empty:
        raise ResultsError(
            f"no results.json below {', '.join(map(str, runs))}; run "
            "'olatbench run --method ssdgs --suite mini' first"
        )
    # only failed or unfinished jobs: no number to put in a table
    if not (frame["status"] == "done").any():
        jobs = frame.drop_duplicates("job_id")["status"].value_counts()
        states = ", ".join(f"{count} {state}" for state, count in sorted(jobs.items()))
        raise ResultsError(
            f"no finished job below {', '.join(map(str, runs))} ({states}); "
            f"'olatbench status {' '.join(map(str, runs))}' says why"
        )
    return frame


def _holds_jobs(path: Path) -> bool:
    """Whether ``path`` is, or holds below it, a job folder (job.json)."""
    from olatbench.bench.store import JOB_FILE

    return path.is_file() or any(path.rglob(JOB_FILE))


def _report_data(runs, suite, methods, metrics, splits, as_json: bool) -> str:
    """``--json`` / ``--format csv``: the selected results as records (`olatbench.reports.tidy`)."""
    from olatbench.reports.runs_tables import checked_blocks, select_runs
    from olatbench.reports.tidy import tidy_records, to_json, to_tidy_csv

    frame = _collect(runs)
    metrics, splits = checked_blocks(frame, metrics, splits)
    records = tidy_records(select_runs(frame, suite, methods), metrics, splits)
    return to_json(records) if as_json else to_tidy_csv(records)


def _report_runs(
    runs,
    suite,
    methods,
    metrics,
    splits,
    layouts,
    average,
    fmt,
    standalone,
    palette,
    rules,
    published,
    seeds,
    figure_format,
    frame_ids,
    output,
    fit=False,
    versus=None,
) -> str:
    from olatbench.reports.novel_lights import novel_lights_table, split_novel
    from olatbench.reports.output import render_tables
    from olatbench.reports.ranking import rank_table
    from olatbench.reports.runs_tables import (
        ablation_table,
        checked_blocks,
        overview_table,
        scene_table,
        select_runs,
    )

    frame = _collect(runs)
    metrics, splits = checked_blocks(frame, metrics, splits)
    everything = frame
    frame, novel = split_novel(frame)  # the novel-light scores get their own table, below

    # one per-scene / overview table per suite holding the selected methods
    suites = [suite] if suite else sorted(set(select_runs(frame, None, methods)["suite"]))
    tables = []
    for layout in layouts:
        if layout == "ablation":
            tables.append(
                ablation_table(
                    frame,
                    suite=suite,
                    metrics=metrics,
                    splits=splits,
                    seeds=seeds,
                    published=published,
                )
            )
            continue
        for name in suites:
            if layout == "scenes":
                tables.append(
                    scene_table(
                        frame,
                        suite=name,
                        methods=methods,
                        metrics=metrics,
                        splits=splits,
                        seeds=seeds,
                        average=average,
                        published=published,
                        versus=versus,
                    )
                )
            else:
                tables.append(
                    overview_table(
                        frame,
                        suite=name,
                        methods=methods,
                        metrics=metrics,
                        splits=splits,
                        seeds=seeds,
                        published=published,
                    )
                )
    if not novel.empty and "ablation" not in layouts:
        for name in suites:
            table = novel_lights_table(everything, suite=name, methods=methods, seeds=seeds)
            if table is not None:
                tables.append(table)
    tables = [rank_table(table, min_values=2) for table in tables]
    figures, notes = [], []
    if fmt == "html" and figure_format != "none":
        from olatbench.reports.figure_files import page_figures
        from olatbench.reports.gallery import report_figures

        selected = frame if suite is None else frame[frame["suite"] == suite]
        drawn, notes = report_figures(selected, frame_ids)
        figures = page_figures(
            drawn, output if figure_format in FIGURE_FILE_FORMATS else None, figure_format
        )
    return render_tables(
        tables,
        fmt,
        standalone=standalone,
        colours=palette,
        rules=rules,
        figures=figures,
        notes=notes,
        fit=fit,
    )


@dataclass(frozen=True)
class _RenderOptions:
    """The options of `olatbench render`, one field per click option (same names)."""

    kind: str | None
    camera_path: Path | None
    orbit: bool
    elevation: float
    radius: float | None
    light: str | None
    light_path: Path | None
    lights_file: Path | None
    envmap: str | None
    samples: int | None
    count: int | None
    start_frame: str | None
    component: str
    fps: float | None
    device: str | None
    resolution: tuple[int, int] | None
    output: Path | None
    quiet: bool


@click.command("render")
@click.argument("run", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option(
    "--sweep",
    "kind",
    type=click.Choice(("light-orbit", "view-orbit", "paper")),
    help="Light 360° (2.4° steps), camera 360° (2° steps), or the paper's trajectory (default: "
    "light-orbit unless --camera-path or --orbit is given).",
)
@click.option(
    "--camera-path",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Render along a nerfstudio camera-path JSON (camera_path frames of camera_to_world, "
    "OpenGL axes, and vertical fov in degrees; render_width/height; fps) in the scene's world "
    "frame.",
)
@click.option(
    "--orbit",
    is_flag=True,
    help="Render an orbit of the camera about the scene centre (see --elevation, "
    "--radius, --frames).",
)
@click.option(
    "--elevation",
    type=click.FloatRange(-89.9, 89.9),
    default=20.0,
    show_default=True,
    help="With --orbit: degrees above the plane through the scene centre.",
)
@click.option(
    "--radius",
    type=click.FloatRange(min=0, min_open=True),
    help="With --orbit: distance from the scene centre in scene units (default: the training "
    "cameras' mean distance).",
)
@click.option(
    "--light",
    help="With --camera-path/--orbit: the light of every frame, a training light index (the "
    "light of that training frame) or a position x,y,z (default: the first test frame's).",
)
@click.option(
    "--light-path",
    type=click.Path(dir_okay=False, path_type=Path),
    help='With --camera-path/--orbit: a JSON {"lights": [{"position": [x, y, z]}, ...]}, one '
    "light per frame (or one for all).",
)
@click.option(
    "--lights",
    "lights_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Render under a lighting file (JSON: point, directional, sphere and rect area lights, "
    "environment maps; docs/relighting.md) instead of one point light: with --camera-path or "
    "--orbit a video, else a still of --start-frame's camera (<name>.png, sRGB, and <name>.exr, "
    "linear).",
)
@click.option(
    "--envmap",
    metavar="NAME|FILE",
    help="Render under an environment map, as --lights: a built-in one (studio, sky, furnace) or "
    "an .exr/.hdr equirectangular file.",
)
@click.option(
    "--samples",
    type=click.IntRange(min=1),
    help="With --lights/--envmap: lights sampled from each environment map and area light "
    "(default: the file's, else 64). The render costs one method render per light.",
)
@click.option(
    "--frames",
    "count",
    type=click.IntRange(min=1),
    help="Spread this many frames over the sweep or camera path (an orbit: its number of frames, "
    "default 120).",
)
@click.option(
    "--start-frame",
    help="Test frame id whose camera and light start the sweep (default: the first).",
)
@click.option(
    "--component",
    default="rgb",
    show_default=True,
    help="What to render: rgb, diffuse, shadow, ...",
)
@click.option(
    "--fps",
    type=click.FloatRange(min=1),
    help="Video frame rate (default: the camera path's, else 30).",
)
@device_option
@click.option(
    "--resolution",
    type=Resolution(),
    help="Frame size N (N×N) or WxH (default: the job's; a camera "
    "path: its render_width × render_height).",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(file_okay=False, path_type=Path),
    help=(
        "Folder for <sweep>.mp4 and <sweep>_frames/ (camera-path.mp4, orbit.mp4; default: "
        "RUN/videos)."
    ),
)
@quiet_option
def render(run: Path, **values) -> None:
    """Render a relighting sweep, a camera path or an orbit of a finished job to an MP4 and a frame
    folder; under a lighting (--lights, --envmap: several lights, area lights, environment maps)
    also a still.

    \b
    Examples:
      olatbench render runs/mini/ssdgs/default/translucent/seed0 --sweep light-orbit
      olatbench render runs/nrhints/ssdgs/default/Pixiu/seed0 --sweep paper --resolution 256x256
      olatbench render runs/mini/ssdgs/default/translucent/seed0 --camera-path path.json --light 0
      olatbench render runs/mini/ssdgs/default/translucent/seed0 --orbit --elevation 30 \\
          --frames 90 --light 1,2,3
      olatbench render runs/mini/ssdgs/default/translucent/seed0 --orbit --envmap studio \\
          --samples 64
      olatbench render runs/mini/ssdgs/default/translucent/seed0 --lights two_lights.json
    """
    from olatbench.datasets.errors import DatasetError
    from olatbench.reports.jobfolder import JobFolder, JobFolderError
    from olatbench.reports.sweeps import subsample
    from olatbench.reports.video import Orbit, RenderRequestError, free_path_frames, render_sweep

    options = _RenderOptions(**values)

    free = options.camera_path is not None or options.orbit
    if options.camera_path is not None and options.orbit:
        raise click.UsageError("give --camera-path or --orbit, not both")
    if options.lights_file is not None or options.envmap is not None:
        _render_lit(run, options)
        return
    if options.samples is not None:
        raise click.UsageError("--samples goes with --lights or --envmap")
    if free and (options.kind or options.start_frame):
        raise click.UsageError("--sweep and --start-frame go without --camera-path and --orbit")
    if not free and (options.light is not None or options.light_path is not None):
        raise click.UsageError("--light and --light-path go with --camera-path or --orbit")
    if options.light is not None and options.light_path is not None:
        raise click.UsageError("give --light or --light-path, not both")
    device = resolved_device(options.device)
    try:
        job = JobFolder.open(run)
    except JobFolderError as error:  # RUN is not a finished job folder
        raise click.UsageError(str(error)) from None
    fps = options.fps
    try:
        frames = None
        if free:
            name = "camera-path" if options.camera_path is not None else "orbit"
            frames, path_fps = free_path_frames(
                job,
                camera_path=options.camera_path,
                light=options.light,
                light_path=options.light_path,
                resolution=options.resolution,
                orbit=Orbit(options.elevation, options.radius, options.count or Orbit.frames)
                if options.orbit
                else None,
            )
            frames = subsample(frames, options.count)
            fps = options.fps or path_fps
        result = render_sweep(
            job,
            name if free else options.kind or "light-orbit",
            options.output or run / "videos",
            count=options.count,
            frame_id=options.start_frame,
            component=options.component,
            fps=fps or 30.0,
            device=device,
            resolution=options.resolution,
            progress=show_progress(options.quiet),
            frames=frames,
        )
    # something asked of the job that it does not have: says what it has
    except RenderRequestError as error:
        raise click.UsageError(str(error)) from None
    except (JobFolderError, DatasetError, RuntimeError, OSError, ValueError) as error:
        raise click.ClickException(
            f"{error}\nCheck the job with 'olatbench status {run.parent.parent.parent}'."
        ) from None
    codec = (
        "H.264"
        if result.encoder != "opencv"
        else "MPEG-4 Part 2 (mp4v; browsers do not play it: install 'olatbench[video]')"
    )
    click.echo(
        f"wrote {result.video} ({codec}, {result.encoder}) and {result.frames} frames in "
        f"{result.frames_dir}"
    )


def _render_lit(run: Path, options: _RenderOptions) -> None:
    """`render` under a lighting (--lights or --envmap): a video along --camera-path/--orbit, else a
    still."""
    from olatbench.datasets.errors import DatasetError
    from olatbench.datasets.lighting import environment_lighting, read_lighting
    from olatbench.reports.jobfolder import JobFolder, JobFolderError
    from olatbench.reports.sweeps import subsample
    from olatbench.reports.video import (
        Orbit,
        RenderRequestError,
        free_path_frames,
        load_relighter,
        render_still,
        render_sweep,
        sample_lighting,
    )

    if options.lights_file is not None and options.envmap is not None:
        raise click.UsageError("give --lights or --envmap, not both")
    if options.kind or options.light is not None or options.light_path is not None:
        raise click.UsageError(
            "--sweep, --light and --light-path move one point light: they go without --lights "
            "and --envmap"
        )
    if options.component != "rgb":
        raise click.UsageError(
            f"--component {options.component}: under --lights/--envmap only rgb adds up over lights"
        )
    still = options.camera_path is None and not options.orbit
    if still and options.count is not None:
        raise click.UsageError(
            "--frames goes with --camera-path or --orbit (without them: one still)"
        )
    if not still and options.start_frame:
        raise click.UsageError("--start-frame goes without --camera-path and --orbit")
    device = resolved_device(options.device)
    try:
        lighting = (
            read_lighting(options.lights_file)
            if options.lights_file is not None
            else environment_lighting(options.envmap, options.samples)
        )
    except DatasetError as error:  # one line naming the file and the field
        raise click.UsageError(str(error)) from None
    try:
        job = JobFolder.open(run)
    except JobFolderError as error:
        raise click.UsageError(str(error)) from None
    progress = show_progress(options.quiet)
    try:
        sampled = sample_lighting(job, lighting, options.samples)
        relighter = load_relighter(job, device, progress)
        if still:
            written = render_still(
                job,
                sampled,
                options.output or run / "videos",
                lighting.name,
                frame_id=options.start_frame,
                resolution=options.resolution,
                progress=progress,
                relighter=relighter,
            )
            click.echo(
                f"wrote {written.png} and {written.exr} (linear) under {lighting.name}: "
                f"{len(sampled)} lights"
            )
            return
        frames, path_fps = free_path_frames(
            job,
            camera_path=options.camera_path,
            resolution=options.resolution,
            orbit=Orbit(options.elevation, options.radius, options.count or Orbit.frames)
            if options.orbit
            else None,
        )
        name = f"{'camera-path' if options.camera_path is not None else 'orbit'}-{lighting.name}"
        result = render_sweep(
            job,
            name,
            options.output or run / "videos",
            fps=options.fps or path_fps or 30.0,
            progress=progress,
            method=relighter,
            frames=subsample(frames, options.count),
            lighting=sampled,
        )
    except RenderRequestError as error:
        raise click.UsageError(str(error)) from None
    except (JobFolderError, DatasetError, RuntimeError, OSError, ValueError) as error:
        raise click.ClickException(
            f"{error}\nCheck the job with 'olatbench status {run.parent.parent.parent}'."
        ) from None
    click.echo(
        f"wrote {result.video} and {result.frames} frames in {result.frames_dir} under "
        f"{lighting.name}: {len(sampled)} lights per frame"
    )
