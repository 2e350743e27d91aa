"""``olatbench datasets download`` and ``olatbench datasets verify``."""

from __future__ import annotations

import os
from pathlib import Path

import click

from olatbench.cli.options import option, quiet_option, show_progress
from olatbench.datasets.download import fetch, manifest, transfer
from olatbench.datasets.download.sources import SOURCES
from olatbench.datasets.errors import printable


def default_data_root() -> Path:
    """``$OLATBENCH_DATA`` or ``./data``: where downloads go and where ``olatbench run`` looks."""
    return Path(os.environ.get("OLATBENCH_DATA", "data"))


@click.command()
@click.argument("suite", type=click.Choice(sorted(SOURCES)))
@click.option("--scenes", help="Comma-separated canonical scene names (default: all of the suite).")
@option(
    "--data-root",
    "root",
    aliases=("--root",),
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Data root (default: $OLATBENCH_DATA or ./data). Scenes land in ROOT/<Scene>.",
)
@click.option(
    "--source", help="Use only this source (see the suite's sources in docs/downloads.md)."
)
@click.option(
    "--mirror",
    help="Base URL replacing the host: a folder URL (http:// or file://) for url "
    "sources, or a Hugging Face compatible endpoint for hf sources.",
)
@click.option("--jobs", default=4, show_default=True, help="Files downloaded in parallel.")
@quiet_option
def download(
    suite: str,
    scenes: str | None,
    root: Path | None,
    source: str | None,
    mirror: str | None,
    jobs: int,
    quiet: bool,
) -> None:
    """Fetch, verify and lay out the official scenes of SUITE.

    Downloads resume where they stopped; archives are checked against published or first-seen sha256
    hashes; unpacking is safe, bounded and atomic; aliases become canonical names. Nothing olatbench
    did not write is deleted: a ROOT/<Scene> it did not download stops that scene, one that differs
    from its manifest is moved aside to ROOT/<Scene>.replaced-<time>. Exit status: 0 when every
    scene is ready, 1 when any failed (each failure says what to do next), 2 for a usage error.

    \b
    Example:
      olatbench datasets download gs3 --scenes Translucent,Lego --data-root ~/olat
    """
    root = root or default_data_root()
    names = [s.strip() for s in scenes.split(",")] if scenes else list(SOURCES[suite])
    unknown = [n for n in names if n not in SOURCES[suite]]
    if unknown:
        raise click.BadParameter(
            f"unknown scenes {', '.join(unknown)}; {suite} has {', '.join(SOURCES[suite])}",
            param_hint="--scenes",
        )
    hints: list[str] = []  # one per failed scene: what to do next
    for name in names:
        try:
            folder = fetch.download_scene(
                suite,
                name,
                root,
                source=source,
                mirror=mirror,
                jobs=jobs,
                progress=show_progress(quiet),
                notify=lambda message: click.echo(message, err=True),
            )
            click.echo(f"{suite}/{name}: ready at {folder}")
        except fetch.ManualStepRequired as error:
            hints.append("follow the instructions above, then rerun")
            click.echo(f"{suite}/{name}: NEEDS A MANUAL STEP\n  {error}", err=True)
        except transfer.DownloadError as error:
            hints.append("rerun the same command to resume")
            click.echo(f"{suite}/{name}: FAILED\n  {error}", err=True)
        except (fetch.FolderInTheWay, ValueError, KeyError, OSError) as error:
            # ValueError: IntegrityError, UnsafeArchiveError, ArchiveError, DatasetError; OSError:
            # the disk
            hints.append("each failure above says what to do")
            message = error.args[0] if isinstance(error, KeyError) else error
            click.echo(f"{suite}/{name}: FAILED\n  {printable(message)}", err=True)
    if hints:
        raise click.ClickException(
            f"{len(hints)} of {len(names)} scenes failed; {'; '.join(dict.fromkeys(hints))}"
        )
    click.echo(f"Run on them with: olatbench run --suite {suite} --data-root {root}")


@click.command()
@click.argument("root", type=click.Path(exists=True, file_okay=False, path_type=Path))
def verify(root: Path) -> None:
    """Re-hash every downloaded scene under ROOT against its recorded manifest.

    \b
    Example:
      olatbench datasets verify ~/olat
    """
    folders = sorted(p.parent for p in root.glob(f"*/{manifest.MANIFEST_NAME}"))
    if not folders:
        raise click.ClickException(
            f"{root}: no scene downloaded by olatbench here "
            f"(try: olatbench datasets download SUITE --data-root {root})"
        )
    found = {folder: manifest.verify_folder(folder) for folder in folders}
    for folder, folder_problems in found.items():
        click.echo(f"{folder.name}: {'DAMAGED' if folder_problems else 'ok'}")
    problems = [problem for folder_problems in found.values() for problem in folder_problems]
    if problems:
        raise click.ClickException("\n".join(problems))
