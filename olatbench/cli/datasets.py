"""``olatbench datasets``: inspect, validate, convert, generate and download OLAT datasets
(verbs load lazily)."""

from __future__ import annotations

import click

from olatbench.cli import LazyGroup

DATASET_COMMANDS = {
    "info": "olatbench.cli.datasets_verbs:info",
    "validate": "olatbench.cli.datasets_verbs:validate",
    "convert": "olatbench.cli.datasets_verbs:convert",
    "synth": "olatbench.cli.synth:synth",
    "download": "olatbench.cli.download:download",
    "verify": "olatbench.cli.download:verify",
}

DATASET_HELP = {
    "info": "Summarise scene folders: format, splits, resolution, colour, lights.",
    "validate": "Check every frame of a dataset; non-zero exit on errors.",
    "convert": "Write a scene in another format (nrhints, gs3, sssgs).",
    "synth": "Render synthetic OLAT scenes (the mini suite).",
    "download": "Download a suite's data.",
    "verify": "Check downloaded data against its manifest.",
}


@click.group(cls=LazyGroup, commands=DATASET_COMMANDS, help_lines=DATASET_HELP)
def datasets() -> None:
    """Inspect, validate, convert and generate OLAT datasets.

    \b
    Examples:
      olatbench datasets info data/nrhints/Pixiu
      olatbench datasets validate data/gs3 --json
      olatbench datasets convert data/gs3/Lego lego_png --to nrhints
    """
