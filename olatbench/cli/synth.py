"""``olatbench datasets synth``: render a synthetic OLAT scene from a recipe, or install (or render)
the mini suite."""

from __future__ import annotations

from pathlib import Path

import click

from olatbench.cli.options import Resolution, option, quiet_option, show_progress
from olatbench.datasets.errors import DatasetError, OutputExistsError


def _machine() -> str:
    """This machine for the reference's ``made_on``: architecture, system, CPU model and its widest
    vector unit."""
    import platform

    model, flags = platform.processor() or "cpu", set()
    try:
        for line in Path("/proc/cpuinfo").read_text(encoding="utf-8").splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name":
                model = value.strip()
            elif key.strip() == "flags":
                flags = set(value.split())
    except OSError:
        pass
    vector = next((flag for flag in ("avx512f", "avx2", "neon", "asimd") if flag in flags), None)
    return f"{platform.machine()} {platform.system()} ({model}{', ' + vector if vector else ''})"


def _report_reference(root: Path, write: bool) -> None:
    """Print each mini scene's comparison with the packaged reference, then that of its ground truth
    under new illumination (or first make them the reference)."""
    import json

    from olatbench.datasets.novel_lights import FOLDER, compare_novel_lights
    from olatbench.datasets.synth.mini import MINI_SCENES, compare_with_reference, manifest_files
    from olatbench.datasets.synth.reference import (
        MINI,
        NOVEL_LIGHTS,
        load_reference,
        write_reference,
    )

    if write:
        synth_info = json.loads((root / MINI_SCENES[0] / "synth.json").read_text(encoding="utf-8"))
        metadata = {
            "generator_version": synth_info["generator_version"],
            "mitsuba_version": synth_info["mitsuba_version"],
            "mitsuba_variant": synth_info["mitsuba_variant"],
            "made_on": _machine(),
        }
        for package, folder in ((MINI, ""), (NOVEL_LIGHTS, FOLDER)):
            scenes = {name: manifest_files(root / name / folder) for name in MINI_SCENES}
            path = write_reference(root, scenes, metadata, package=package)
            click.echo(f"wrote the {package.label} to {path} and the scenes' archives beside it")
    for package, compare in ((MINI, compare_with_reference), (NOVEL_LIGHTS, compare_novel_lights)):
        reference = load_reference(package=package)
        for name in MINI_SCENES:
            click.echo(compare(root / name).summary(reference))


@click.command()
@click.option(
    "--recipe",
    "recipe_name",
    default=None,
    metavar="NAME|FILE",
    help="A built-in recipe (see --list) or a recipe JSON file.",
)
@click.option(
    "--format",
    "fmt",
    type=click.Choice(["nrhints", "gs3", "sssgs"]),
    default="nrhints",
    show_default=True,
    help="Output format.",
)
@option(
    "-o",
    "--output",
    "out_dir",
    aliases=("--out",),
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Output scene folder (with --mini: the suite root; default the cache).",
)
@option(
    "--resolution",
    "res",
    aliases=("--res",),
    default=None,
    type=Resolution(minimum=4),
    help="Image size (default: the recipe's).",
)
@click.option("--spp", type=click.IntRange(min=1), default=None, help="Samples per pixel.")
@click.option(
    "--train",
    "n_train",
    type=click.IntRange(min=1),
    default=None,
    help="Number of training images.",
)
@click.option(
    "--test", "n_test", type=click.IntRange(min=0), default=None, help="Number of test images."
)
@click.option("--seed", type=int, default=None, help="Seed of the rig and the samplers.")
@click.option(
    "--novel-views/--seen-views",
    "novel_views",
    default=None,
    help=(
        "Test cameras new (novel views) or drawn from the training cameras (default: the recipe's)."
    ),
)
@click.option("--no-geometry", is_flag=True, help="Skip the diagnostic geometry pass.")
@click.option(
    "--lights",
    "lights_file",
    type=click.Path(dir_okay=False, path_type=Path),
    help="Instead of the OLAT scene, render the recipe's test cameras under this lighting file "
    "(JSON: point, directional, area lights, environment maps; docs/relighting.md) into -o as "
    "<frame_id>.exr (linear), lighting.json and lit.json: ground truth under new illumination (-o "
    "SCENE/novel_lights/NAME makes it condition NAME of the recipe's scene SCENE).",
)
@click.option(
    "--mini",
    is_flag=True,
    help="Install (or verify) the mini suite, the packaged reference renders with their ground "
    "truth under new illumination, instead of one recipe.",
)
@click.option(
    "--render",
    "render_mini",
    is_flag=True,
    help="With --mini: render the suite and its ground truth under new illumination with Mitsuba "
    "on this machine instead (into ~/.cache/olatbench/mini-rendered unless -o) and compare them "
    "with the reference.",
)
@click.option(
    "--write-reference",
    is_flag=True,
    help="With --mini --render, for maintainers: make this machine's renders the packaged "
    "reference (after a generator or Mitsuba pin change; commit the result).",
)
@click.option("--list", "list_recipes", is_flag=True, help="List the built-in recipes and exit.")
@quiet_option
def synth(
    recipe_name: str | None,
    fmt: str,
    out_dir: Path | None,
    res: tuple[int, int] | None,
    spp: int | None,
    n_train: int | None,
    n_test: int | None,
    seed: int | None,
    novel_views: bool | None,
    no_geometry: bool,
    lights_file: Path | None,
    mini: bool,
    render_mini: bool,
    write_reference: bool,
    list_recipes: bool,
    quiet: bool,
) -> None:
    """Render a synthetic OLAT scene with Mitsuba 3 (pip install 'olatbench[synth]'), or install the
    mini suite.

    \b
    Examples:
      olatbench datasets synth --recipe aniso_metal -o data/synth/aniso_metal
      olatbench datasets synth --recipe my_recipe.json --format gs3 -o data/synth/mine \\
          --resolution 128 --spp 256
      olatbench datasets synth --mini                # the mini suite into ~/.cache/olatbench/mini
      olatbench datasets synth --mini --render       # render it here with Mitsuba and compare
      olatbench datasets synth --recipe aniso_metal --lights two_lights.json \\
          -o data/synth/aniso_metal/novel_lights/two

    The mini suite is the packaged reference renders: --mini installs them
    (every file's sha256 checked), so every machine trains on the same bytes, with each scene's
    ground truth under the novel-light conditions in SCENE/novel_lights/ (docs/relighting.md).
    --mini --render renders both with this machine's Mitsuba instead and says whether they are
    identical to the reference (if not: which files differ, how many images were compared and their
    max and mean |Δ|); train on it with --data-root.
    """
    from olatbench.datasets.synth.backend import MitsubaMissing
    from olatbench.datasets.synth.recipe import RECIPES, get_recipe, recipe_names

    if list_recipes:
        for name in recipe_names():
            recipe = RECIPES[name]
            click.echo(
                f"{name:16s} {recipe.shape:12s} {recipe.material.kind:15s} "
                f"{recipe.resolution[0]}x{recipe.resolution[1]} spp={recipe.spp} "
                f"train={recipe.train} test={recipe.test}"
            )
        return
    try:
        if write_reference and not (mini and render_mini):
            raise click.UsageError("--write-reference needs --mini --render")
        if mini and lights_file is not None:
            raise click.UsageError("--lights goes with --recipe, not --mini")
        if mini:
            from olatbench.datasets.novel_lights import ensure_novel_lights
            from olatbench.datasets.synth.mini import MINI_SCENES, ensure_mini_suite

            # compare=False: _report_reference below prints the comparison
            root = ensure_mini_suite(
                out_dir, progress=show_progress(quiet), compare=False, render=render_mini
            )
            for name in MINI_SCENES:
                ensure_novel_lights(root / name, render=render_mini, progress=show_progress(quiet))
            _report_reference(root, write_reference)
            data_root = f" --data-root {root}" if render_mini or out_dir is not None else ""
            click.echo(
                f"mini suite ready in {root}. Next: olatbench run --method ssdgs --suite "
                f"mini{data_root}"
            )
            return
        if render_mini:
            raise click.UsageError("--render goes with --mini")
        if recipe_name is None or out_dir is None:
            raise click.UsageError("give --recipe and --output (or --mini, or --list)")
        from olatbench.datasets.synth.generate import generate

        try:
            recipe = (
                get_recipe(recipe_name)
                .with_overrides(
                    resolution=res,
                    spp=spp,
                    train=n_train,
                    test=n_test,
                    seed=seed,
                    novel_views=novel_views,
                )
                .validate()
            )
        except (ValueError, FileNotFoundError, KeyError) as error:  # what was asked is not a recipe
            raise click.UsageError(f"{error}. See: olatbench datasets synth --list") from None
        if lights_file is not None:
            from olatbench.datasets.lighting import read_lighting
            from olatbench.datasets.synth.lit import render_lit

            try:
                lighting = read_lighting(lights_file)
            except DatasetError as error:  # one line naming the file and the field
                raise click.UsageError(str(error)) from None
            render_lit(recipe, lighting, out_dir, progress=show_progress(quiet))
            click.echo(
                f"wrote {recipe.test} test views of {recipe.name} under {lighting.name} to "
                f"{out_dir} (<frame_id>.exr, linear; lit.json)"
            )
            return
        generate(recipe, out_dir, fmt, progress=show_progress(quiet), geometry=not no_geometry)
    except OutputExistsError as error:
        raise click.UsageError(str(error)) from None
    except MitsubaMissing as error:
        raise click.ClickException(str(error)) from None
    except (ValueError, FileNotFoundError, DatasetError) as error:
        raise click.ClickException(f"{error}. See: olatbench datasets synth --list") from None
    click.echo(f"wrote {recipe.name} ({fmt}) to {out_dir}. Next: olatbench datasets info {out_dir}")
