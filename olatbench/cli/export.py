"""``olatbench export``: a finished job's Gaussians as a PLY that splat viewers open."""

from __future__ import annotations

from pathlib import Path

import click

from olatbench.atomic import WriteError


@click.command("export", context_settings={"help_option_names": ["-h", "--help"]})
@click.argument("job", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="The PLY file to write.")
def export(job: Path, output: Path) -> None:
    """Write the trained Gaussians of the finished JOB folder as a PLY in the layout of 3D Gaussian Splatting.

    Centres, log-scales, wxyz rotations and opacity logits as trained; the colour as degree-0 spherical harmonics
    of the method's diffuse albedo (SSD-GS, GS³; 3DGS: its own SH coefficients); the method's other per-Gaussian
    attributes as extra properties (<name>_<i>). Splat viewers and editors that read properties by name
    (SuperSplat, nerfstudio's importer) open the file; docs/export.md lists the properties.

    \b
    Example:
      olatbench export runs/mini/ssdgs/default/translucent/seed0 -o translucent.ply
    """
    from olatbench.bench.export import export_ply
    from olatbench.bench.restore import RestoreError

    try:
        exported = export_ply(job, output)
    except RestoreError as error:
        raise click.ClickException(str(error)) from None
    except WriteError as error:  # a read-only folder or a full disk: one line, the old file (if any) untouched
        raise click.ClickException(f"{error}; choose another -o") from None
    extras = f"; extra properties from {', '.join(exported.extras)}" if exported.extras else ""
    click.echo(f"wrote {exported.path}: {exported.gaussians} Gaussians at step {exported.step}{extras}")
