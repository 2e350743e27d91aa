"""Synthetic OLAT scenes rendered with Mitsuba 3 (optional extra ``olatbench[synth]``).

>>> from olatbench.datasets.synth import get_recipe, generate
>>> recipe = get_recipe("aniso_metal").with_overrides(resolution=(64, 64), train=50, test=10)
>>> generate(recipe, "data/synth/aniso_metal", fmt="nrhints")

Importing this package needs numpy alone; Mitsuba is imported when the first frame is rendered.
See ``docs/synthetic-data.md``.
"""

from olatbench.datasets.synth.generate import RenderedScene, generate, render_recipe, write_rendered
from olatbench.datasets.synth.mini import MINI_SCENES, ensure_mini_suite
from olatbench.datasets.synth.recipe import (
    RECIPES,
    CameraRig,
    LightRig,
    Material,
    Recipe,
    get_recipe,
    recipe_names,
)

__all__ = [
    "MINI_SCENES",
    "RECIPES",
    "CameraRig",
    "LightRig",
    "Material",
    "Recipe",
    "RenderedScene",
    "ensure_mini_suite",
    "generate",
    "get_recipe",
    "recipe_names",
    "render_recipe",
    "write_rendered",
]
