"""The ``info``, ``validate`` and ``convert`` verbs of ``olatbench datasets``."""

from __future__ import annotations

import json
from pathlib import Path

import click

from olatbench.cli.options import quiet_option, show_progress
from olatbench.datasets.errors import DatasetError, OutputExistsError


def _scene_folders(path: Path) -> list[Path]:
    from olatbench.datasets.info import find_scene_folders

    try:
        return find_scene_folders(path)
    except DatasetError as error:
        raise click.UsageError(
            f"{error}. Check the path, e.g. olatbench datasets info data/nrhints/Pixiu"
        ) from None


@click.command()
@click.argument(
    "paths", nargs=-1, required=True, type=click.Path(exists=True, file_okay=False, path_type=Path)
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["nrhints", "gs3", "sssgs"]),
    default=None,
    help="Skip auto-detection.",
)
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")
def info(paths: tuple[Path, ...], fmt: str | None, as_json: bool) -> None:
    """Summarise each scene folder PATH, or every scene folder inside it.

    \b
    Examples:
      olatbench datasets info data/nrhints
      olatbench datasets info data/nrhints/Pixiu data/gs3/Lego
    """
    from olatbench.datasets import load_scene
    from olatbench.datasets.info import format_summary, scene_summary

    folders = list(dict.fromkeys(folder for path in paths for folder in _scene_folders(path)))
    summaries, failures = [], []
    for folder in folders:
        try:
            summaries.append(scene_summary(load_scene(folder, fmt)))
        except DatasetError as error:
            failures.append((folder, error))
    if as_json:
        click.echo(json.dumps(summaries, indent=2))
    elif summaries:
        click.echo("\n\n".join(format_summary(summary) for summary in summaries))
    if failures:
        folder, error = failures[0]
        more = f" ({len(failures) - 1} more unreadable scenes)" if len(failures) > 1 else ""
        raise click.ClickException(f"{error}{more}. Run: olatbench datasets validate {folder}")


@click.command()
@click.argument("path", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["nrhints", "gs3", "sssgs"]),
    default=None,
    help="Skip auto-detection.",
)
@click.option(
    "--no-decode", is_flag=True, help="Check files and keys but do not decode the images."
)
@click.option("--json", "as_json", is_flag=True, help="Print the reports as JSON.")
@click.option(
    "--max-issues",
    default=20,
    show_default=True,
    help="Issues listed per scene in the text output.",
)
@quiet_option
def validate(
    path: Path, fmt: str | None, no_decode: bool, as_json: bool, max_issues: int, quiet: bool
) -> None:
    """Check every frame of a scene folder (or of every scene folder inside PATH).

    Exits with status 1 when any error is found.

    \b
    Example:
      olatbench datasets validate data/sssgs --json
    """
    from olatbench.datasets.validate import validate_folder

    reports = [
        validate_folder(folder, fmt, decode=not no_decode, progress=show_progress(quiet or as_json))
        for folder in _scene_folders(path)
    ]
    if as_json:
        click.echo(json.dumps([report.to_dict() for report in reports], indent=2))
    else:
        rows = [("scene", "format", "frames", "errors", "warnings")]
        for report in reports:
            rows.append(
                (
                    report.scene or Path(report.root).name,
                    report.format or "?",
                    str(sum(report.frames.values())),
                    str(len(report.errors)),
                    str(len(report.issues) - len(report.errors)),
                )
            )
        widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
        for row in rows:
            click.echo(
                "  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True))
            )
        for report in reports:
            for issue in report.issues[:max_issues]:
                click.echo(f"{issue.severity}: {issue}")
            if len(report.issues) > max_issues:
                click.echo(
                    f"... {len(report.issues) - max_issues} more issues in {report.root} (use "
                    "--json)"
                )
    if not all(report.ok for report in reports):
        if not as_json:
            click.echo(
                "validation failed: fix the errors above, or see them all with --json", err=True
            )
        raise SystemExit(1)


@click.command()
@click.argument("src", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.argument("dst", type=click.Path(file_okay=False, path_type=Path))
@click.option(
    "--to",
    "target",
    type=click.Choice(["nrhints", "gs3", "sssgs"]),
    required=True,
    help="Format to write.",
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["nrhints", "gs3", "sssgs"]),
    default=None,
    help="Format of SRC (default: auto-detected).",
)
@click.option("--overwrite", is_flag=True, help="Write over an existing scene in DST.")
@quiet_option
def convert(
    src: Path, dst: Path, target: str, fmt: str | None, overwrite: bool, quiet: bool
) -> None:
    """Write the scene in SRC into DST in another format.

    Cameras and lights are kept exactly; pixels go through linear light with straight alpha and are
    stored as the target format stores them. A camera path split ("path") has no SSS-GS equivalent
    and is dropped with a note.

    \b
    Example:
      olatbench datasets convert data/gs3/Lego lego_nrhints --to nrhints
    """
    from olatbench.datasets import load_scene
    from olatbench.datasets.convert import frame_pixels, write_scene
    from olatbench.progress import progress_bar

    try:
        scene = load_scene(src, fmt)
        if target == "sssgs" and scene.frames.get("path"):
            click.echo(
                f"note: dropping the {len(scene.frames['path'])} camera-path frames (no SSS-GS "
                "file)"
            )
            scene.frames.pop("path")
        images = sum(frame.image_path is not None for frame in scene)
        with progress_bar(
            total=images,
            desc=f"convert {scene.name}",
            unit="image",
            disable=not show_progress(quiet),
        ) as bar:

            def pixels(frame):
                bar.update(1)
                return frame_pixels(frame)

            out = write_scene(scene, dst, target, pixels, overwrite=overwrite)
    except OutputExistsError as error:
        raise click.UsageError(f"{error} (--overwrite replaces it)") from None
    except DatasetError as error:
        raise click.ClickException(f"{error}. Run: olatbench datasets validate {src}") from None
    click.echo(f"wrote {scene.name} as {target} to {out}")
