"""``olatbench export``: a finished job's Gaussians as a PLY that splat viewers open."""

from __future__ import annotations

from pathlib import Path

import click

from olatbench.atomic import WriteError
from olatbench.cli.options import device_option, quiet_option, resolved_device, show_progress


@click.command("export", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("job", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, path_type=Path),
    required=True,
    help="The PLY file to write.",
)
@click.option(
    "--under-light",
    metavar="LIGHT",
    help="Bake the colours under this light instead of the albedo: a training light index (the "
    "light of that training frame), a position x,y,z in scene units, a lighting file (.json, as "
    "'render --lights'; docs/relighting.md) or an environment map (studio, sky, furnace, or an "
    ".exr/.hdr file). A picture of the model under that light, not a relightable model.",
)
@click.option(
    "--samples",
    type=click.IntRange(min=1),
    help="With --under-light a lighting file or map: lights sampled from each environment map and "
    "area light (default: the file's, else 64).",
)
@click.option(
    "--sh-degree",
    type=click.IntRange(0, 3),
    default=0,
    show_default=True,
    help="With --under-light: the SH degree fitted to the colours seen from the cameras (0: their "
    "mean, the view-independent part; 1-3 keep some view dependence).",
)
@click.option(
    "--view",
    metavar="FRAME_ID",
    help="With --under-light: bake the colours as this frame's camera sees them (exact from that "
    "camera) instead of fitting them over the training cameras.",
)
@click.option(
    "--max-views",
    type=click.IntRange(min=1),
    default=64,
    show_default=True,
    help="With --under-light: fit over at most this many training cameras, spread evenly.",
)
@device_option
@quiet_option
def export(
    job: Path,
    output: Path,
    under_light: str | None,
    samples: int | None,
    sh_degree: int,
    view: str | None,
    max_views: int,
    device: str,
    quiet: bool,
) -> None:
    """Write the trained Gaussians of the finished JOB folder as a PLY in the layout of 3D Gaussian
    Splatting.

    Centres, log-scales, wxyz rotations and opacity logits as trained; the colour as degree-0
    spherical harmonics of the method's diffuse albedo (SSD-GS, GS³; 3DGS: its own SH coefficients),
    or with --under-light the colour under that light (SSD-GS, GS³), fitted as SH over the training
    cameras (or taken from one --view); the method's other per-Gaussian attributes as extra
    properties (<name>_<i>). Splat viewers and editors that read properties by name (SuperSplat,
    nerfstudio's importer) open the file; docs/export.md lists the properties.

    \b
    Examples:
      olatbench export runs/mini/ssdgs/default/translucent/seed0 -o translucent.ply
      olatbench export runs/mini/ssdgs/default/translucent/seed0 --under-light 0 -o lit.ply
      olatbench export runs/mini/ssdgs/default/translucent/seed0 --under-light 0,0,4 \\
          --sh-degree 3 -o lit3.ply
      olatbench export runs/mini/ssdgs/default/translucent/seed0 --under-light studio \\
          --samples 32 -o studio.ply
    """
    from olatbench.bench.export import Bake, BakeRequestError, export_ply
    from olatbench.bench.restore import NotAJobFolderError, RestoreError

    if under_light is None and (view is not None or sh_degree != 0):
        raise click.UsageError("--view and --sh-degree go with --under-light")
    if view is not None and sh_degree != 0:
        raise click.UsageError(
            "--view bakes the colours one camera sees: --sh-degree 0 (a fit over one direction "
            "has no view dependence to keep)"
        )
    lighting = _lighting(under_light) if under_light is not None else None
    if samples is not None and lighting is None:
        raise click.UsageError(
            "--samples goes with --under-light a lighting file or an environment map"
        )
    bake = (
        Bake(under_light, sh_degree, view, max_views, lighting, samples)
        if under_light is not None
        else None
    )
    device = resolved_device(device) if bake else "cpu"
    try:
        exported = export_ply(job, output, bake, device=device, progress=show_progress(quiet))
    # what cannot be baked (says what can); no job folder
    except (BakeRequestError, NotAJobFolderError) as error:
        raise click.UsageError(str(error)) from None
    except RestoreError as error:
        raise click.ClickException(str(error)) from None
    # a read-only folder or a full disk: one line, the old file (if any) untouched
    except WriteError as error:
        raise click.ClickException(f"{error}; choose another -o") from None
    extras = f"; extra properties from {', '.join(exported.extras)}" if exported.extras else ""
    click.echo(
        f"wrote {exported.path}: {exported.gaussians} Gaussians at step {exported.step}{extras}"
    )


def _lighting(value: str):
    """The lighting ``--under-light`` names (a .json lighting file, a built-in map, an .exr/.hdr
    map), or None for one light (a training light index or x,y,z); a bad lighting file is a usage
    error naming the file and field."""
    from olatbench.datasets.errors import DatasetError
    from olatbench.datasets.lighting import BUILT_IN_MAPS, environment_lighting, read_lighting

    suffix = Path(value).suffix.lower()
    try:
        if suffix == ".json":
            return read_lighting(value)
        if value in BUILT_IN_MAPS or suffix in (".exr", ".hdr"):
            return environment_lighting(value)
    except DatasetError as error:
        raise click.UsageError(str(error)) from None
    return None
