"""``olatbench datasets synth``: render a synthetic OLAT scene from a recipe (or the whole mini suite)."""

from __future__ import annotations

from pathlib import Path

import click

from olatbench.cli.options import Resolution, option, quiet_option, show_progress
from olatbench.datasets.errors import DatasetError, OutputExistsError


def _report_reference(root: Path, write: bool) -> None:
    """Print each mini scene's comparison with the packaged reference (or replace the reference)."""
    import json
    import platform

    from olatbench.datasets.synth.mini import MINI_SCENES, compare_with_reference, manifest_files
    from olatbench.datasets.synth.reference import load_reference, write_reference

    if write:
        synth_info = json.loads((root / MINI_SCENES[0] / "synth.json").read_text(encoding="utf-8"))
        scenes = {name: manifest_files(root / name) for name in MINI_SCENES}
        path = write_reference(root, scenes, {
            "generator_version": synth_info["generator_version"], "mitsuba_version": synth_info["mitsuba_version"],
            "mitsuba_variant": synth_info["mitsuba_variant"],
            "made_on": f"{platform.machine()} {platform.system()} ({platform.processor() or 'cpu'})"})
        click.echo(f"wrote the reference to {path}")
    reference = load_reference()
    for name in MINI_SCENES:
        click.echo(compare_with_reference(root / name, reference).summary(reference))


@click.command()
@click.option("--recipe", "recipe_name", default=None, metavar="NAME|FILE",
              help="A built-in recipe (see --list) or a recipe JSON file.")
@click.option("--format", "fmt", type=click.Choice(["nrhints", "gs3", "sssgs"]), default="nrhints",
              show_default=True, help="Output format.")
@option("-o", "--output", "out_dir", aliases=("--out",), type=click.Path(file_okay=False, path_type=Path),
       default=None, help="Output scene folder (with --mini: the suite root; default the cache).")
@option("--resolution", "res", aliases=("--res",), default=None, type=Resolution(minimum=4),
        help="Image size (default: the recipe's).")
@click.option("--spp", type=click.IntRange(min=1), default=None, help="Samples per pixel.")
@click.option("--train", "n_train", type=click.IntRange(min=1), default=None, help="Number of training images.")
@click.option("--test", "n_test", type=click.IntRange(min=0), default=None, help="Number of test images.")
@click.option("--seed", type=int, default=None, help="Seed of the rig and the samplers.")
@click.option("--novel-views/--seen-views", "novel_views", default=None,
              help="Test cameras new (novel views) or drawn from the training cameras (default: the recipe's).")
@click.option("--no-geometry", is_flag=True, help="Skip the diagnostic geometry pass.")
@click.option("--mini", is_flag=True, help="Render (or verify) the mini suite instead of one recipe.")
@click.option("--write-reference", is_flag=True,
              help="With --mini, for maintainers: make this machine's mini renders the packaged reference "
                   "(after a generator or Mitsuba pin change; commit the result).")
@click.option("--list", "list_recipes", is_flag=True, help="List the built-in recipes and exit.")
@quiet_option
def synth(recipe_name: str | None, fmt: str, out_dir: Path | None, res: tuple[int, int] | None, spp: int | None,
          n_train: int | None, n_test: int | None, seed: int | None, novel_views: bool | None, no_geometry: bool,
          mini: bool, write_reference: bool, list_recipes: bool, quiet: bool) -> None:
    """Render a synthetic OLAT scene with Mitsuba 3 (needs: pip install 'olatbench[synth]').

    \b
    Examples:
      olatbench datasets synth --recipe aniso_metal -o data/synth/aniso_metal
      olatbench datasets synth --recipe my_recipe.json --format gs3 -o data/synth/mine --resolution 128 --spp 256
      olatbench datasets synth --mini                # the mini suite into ~/.cache/olatbench/mini

    With --mini each scene is compared with the packaged reference renders and the command says whether
    this machine's data is identical to them (and if not, which files differ and by how much).
    """
    from olatbench.datasets.synth.backend import MitsubaMissing
    from olatbench.datasets.synth.recipe import RECIPES, get_recipe, recipe_names

    if list_recipes:
        for name in recipe_names():
            recipe = RECIPES[name]
            click.echo(f"{name:16s} {recipe.shape:12s} {recipe.material.kind:15s} "
                       f"{recipe.resolution[0]}x{recipe.resolution[1]} spp={recipe.spp} "
                       f"train={recipe.train} test={recipe.test}")
        return
    try:
        if mini:
            from olatbench.datasets.synth.mini import ensure_mini_suite

            # compare=False: _report_reference below prints the comparison
            root = ensure_mini_suite(out_dir, progress=show_progress(quiet), compare=False)
            _report_reference(root, write_reference)
            click.echo(f"mini suite ready in {root}. Next: olatbench run --method ssdgs --suite mini")
            return
        if write_reference:
            raise click.UsageError("--write-reference needs --mini")
        if recipe_name is None or out_dir is None:
            raise click.UsageError("give --recipe and --output (or --mini, or --list)")
        from olatbench.datasets.synth.generate import generate

        try:
            recipe = get_recipe(recipe_name).with_overrides(
                resolution=res, spp=spp, train=n_train, test=n_test, seed=seed,
                novel_views=novel_views).validate()
        except (ValueError, FileNotFoundError, KeyError) as error:  # what was asked is not a recipe
            raise click.UsageError(f"{error}. See: olatbench datasets synth --list") from None
        generate(recipe, out_dir, fmt, progress=show_progress(quiet), geometry=not no_geometry)
    except OutputExistsError as error:
        raise click.UsageError(str(error)) from None
    except MitsubaMissing as error:
        raise click.ClickException(str(error)) from None
    except (ValueError, FileNotFoundError, DatasetError) as error:
        raise click.ClickException(f"{error}. See: olatbench datasets synth --list") from None
    click.echo(f"wrote {recipe.name} ({fmt}) to {out_dir}. Next: olatbench datasets info {out_dir}")
