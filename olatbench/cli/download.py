"""``olatbench datasets download`` and ``olatbench datasets verify``."""

from __future__ import annotations

import os
from pathlib import Path

import click

from olatbench.cli.options import option, quiet_option, show_progress
from olatbench.datasets.download import fetch, manifest, transfer
from olatbench.datasets.download.archives import UnsafeArchiveError
from olatbench.datasets.download.sources import SOURCES
from olatbench.datasets.errors import DatasetError


def default_data_root() -> Path:
    """``$OLATBENCH_DATA`` or ``./data``: where downloads go and where ``olatbench run`` looks."""
    return Path(os.environ.get("OLATBENCH_DATA", "data"))


@click.command()
@click.argument("suite", type=click.Choice(sorted(SOURCES)))
@click.option("--scenes", help="Comma-separated canonical scene names (default: all of the suite).")
@option("--data-root", "root", aliases=("--root",), type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Data root (default: $OLATBENCH_DATA or ./data). Scenes land in ROOT/<Scene>.")
@click.option("--source", help="Use only this source (see the suite's sources in docs/downloads.md).")
@click.option("--mirror", help="Base URL replacing the host: a folder URL (http:// or file://) for url "
                               "sources, or a Hugging Face compatible endpoint for hf sources.")
@click.option("--jobs", default=4, show_default=True, help="Files downloaded in parallel.")
@quiet_option
def download(suite: str, scenes: str | None, root: Path | None, source: str | None, mirror: str | None,
             jobs: int, quiet: bool) -> None:
    """Fetch, verify and lay out the official scenes of SUITE.

    Downloads resume where they stopped; archives are checked against published or first-seen sha256
    hashes; unpacking is safe and atomic; aliases become canonical names.

    \b
    Example:
      olatbench datasets download gs3 --scenes Translucent,Lego --data-root ~/olat
    """
    root = root or default_data_root()
    names = [s.strip() for s in scenes.split(",")] if scenes else list(SOURCES[suite])
    unknown = [n for n in names if n not in SOURCES[suite]]
    if unknown:
        raise click.BadParameter(f"unknown scenes {', '.join(unknown)}; {suite} has {', '.join(SOURCES[suite])}",
                                 param_hint="--scenes")
    failed, manual = 0, 0
    for name in names:
        try:
            folder = fetch.download_scene(suite, name, root, source=source, mirror=mirror, jobs=jobs,
                                          progress=show_progress(quiet))
            click.echo(f"{suite}/{name}: ready at {folder}")
        except fetch.ManualStepRequired as error:
            failed, manual = failed + 1, manual + 1
            click.echo(f"{suite}/{name}: NEEDS A MANUAL STEP\n  {error}", err=True)
        except (transfer.DownloadError, manifest.IntegrityError, UnsafeArchiveError,
                DatasetError, ValueError, KeyError) as error:
            failed += 1
            click.echo(f"{suite}/{name}: FAILED\n  {error}", err=True)
    if failed:
        hint = "follow the instructions above, then rerun" if manual == failed else "rerun the same command to resume"
        raise click.ClickException(f"{failed} of {len(names)} scenes failed; {hint}")
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
        raise click.ClickException(f"{root}: no scene downloaded by olatbench here "
                                   f"(try: olatbench datasets download SUITE --data-root {root})")
    found = {folder: manifest.verify_folder(folder) for folder in folders}
    for folder, folder_problems in found.items():
        click.echo(f"{folder.name}: {'DAMAGED' if folder_problems else 'ok'}")
    problems = [problem for folder_problems in found.values() for problem in folder_problems]
    if problems:
        raise click.ClickException("\n".join(problems))
