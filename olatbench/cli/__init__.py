"""The ``olatbench`` command: a thin, lazily loaded front over the library layers.

Each verb lives in its own module and is imported only when it is invoked, so
``olatbench --help`` and the dataset verbs never import torch.
"""

from __future__ import annotations

import importlib
import io
import sys

import click

from olatbench import __version__
from olatbench.cli.options import without_hidden_suggestions
from olatbench.numerics import pin_numerics

# verb -> "module:attribute" of a click command or group
COMMANDS: dict[str, str] = {
    "datasets": "olatbench.cli.datasets:datasets",
    "methods": "olatbench.cli.methods:methods",
    "run": "olatbench.cli.run:run",
    "status": "olatbench.cli.run:status",
    "evaluate": "olatbench.cli.metrics:evaluate",
    "metrics": "olatbench.cli.metrics:metrics",
    "weights": "olatbench.cli.metrics:weights",
    "report": "olatbench.cli.report:report",
    "render": "olatbench.cli.report:render",
    "export": "olatbench.cli.export:export",
    "view": "olatbench.cli.view:view",
    "doctor": "olatbench.cli.doctor:doctor",
}

HELP_LINES: dict[str, str] = {
    "datasets": "Inspect, validate, convert and generate OLAT datasets.",
    "methods": "List methods and show their presets.",
    "run": "Train and evaluate methods on a suite (resumable).",
    "status": "Show the state of the jobs in a run folder.",
    "evaluate": "Score a folder of renders against a scene's ground truth.",
    "metrics": "Explain the metric protocols.",
    "weights": "Install and locate the LPIPS weights.",
    "report": "Build the paper's tables and figures from results.json files.",
    "render": "Render relighting sweeps, camera paths and orbits (videos) of a finished job.",
    "export": (
        "Write a finished job's Gaussians as a PLY for splat viewers (or baked under a light)."
    ),
    "view": "Interactive relighting viewer for trained jobs (web, viser).",
    "doctor": "Show what this machine supports and how to fix what is missing.",
}


class LazyGroup(click.Group):
    """A click group whose sub-commands are imported on first use.

    ``commands`` maps a verb to ``"module:attribute"``; ``help_lines`` gives the one-line
    summaries shown by ``--help`` without importing the modules.
    """

    def __init__(
        self,
        *args,
        commands: dict[str, str] | None = None,
        help_lines: dict[str, str] | None = None,
        **kwargs,
    ) -> None:
        super().__init__(*args, **kwargs)
        self.lazy_commands = COMMANDS if commands is None else commands
        self.help_lines = HELP_LINES if help_lines is None else help_lines

    def main(self, *args, **kwargs):  # type: ignore[override]
        """Set the numerics pins before any verb can import torch
        (`olatbench.numerics.pin_numerics`), and let output show a file name that is not UTF-8
        (as ``\\udcff``) instead of failing on it."""
        pin_numerics()
        for stream in (sys.stdout, sys.stderr):
            if isinstance(stream, io.TextIOWrapper) and stream.errors == "strict":
                stream.reconfigure(errors="backslashreplace")
        return super().main(*args, **kwargs)

    def invoke(self, ctx: click.Context):  # type: ignore[override]
        """Run the verb; a mistyped option is offered the shown spellings only
        (`without_hidden_suggestions`)."""
        try:
            return super().invoke(ctx)
        except click.NoSuchOption as error:
            raise without_hidden_suggestions(error) from None

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(self.lazy_commands) | set(self.commands))

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        if name in self.commands:
            return self.commands[name]
        target = self.lazy_commands.get(name)
        if target is None:
            return None
        module_name, attribute = target.split(":")
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as error:
            if error.name and error.name.startswith("olatbench"):
                raise click.ClickException(
                    f"'{name}' is not available in this build ({error})."
                ) from error
            raise click.ClickException(
                f"'olatbench {name}' needs the package '{error.name}'. Install it, e.g. "
                f"pip install torch==2.13.0 && pip install 'olatbench[all]'"
            ) from error
        return getattr(module, attribute)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, self.help_lines.get(name, "")) for name in self.list_commands(ctx)]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="olatbench")
def main() -> None:
    """Benchmark relightable 3D reconstruction on OLAT data.

    \b
    Typical session:
      olatbench run --method ssdgs --suite mini     # generate data, train, evaluate
      olatbench report runs/                        # the paper-style tables
    """
