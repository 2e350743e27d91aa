"""Presets derived from the scene, for scenes of no benchmark suite
(``run --data``, ``[suites.NAME]``).

The paper's presets were tuned for the paper's datasets (512² images, hundreds of views, 100K GPU
steps), and the mini presets for the mini scenes (64², 100 training views, 3000 CPU steps). A user's
own capture is neither, so a native method declares its small-scene recipe
(`MethodSpec.scene_recipe`: the ``mini`` preset of 3DGS and GS³, SSD-GS's ``own-data``, its mini
preset over the official code's switches) and the runner scales it from the mini scenes to the
scene: the run length with the number of training images, the Gaussian budget and initial count with
the pixel count, the light-view pass with the image side; never below the recipe (a scene smaller
than the mini ones gets the recipe as it is) and never above the paper's length and budget.
Iteration-valued fields stay at the recipe's reference length and scale with ``iterations``
(with the floors of `GaussianConfig.density_windows`). Nothing real-capture-specific is switched on:
camera and light refinement and test-pose fitting stay off (ask for them with ``--variant nrhints``,
the paper's real-capture preset). Every value comes with the reason it was chosen, which
``run --dry-run`` and ``methods show --data DIR`` print.

Pure functions of plain data (no torch, no files): `derive_preset` is tested without training.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

#: The scenes the recipes were tuned on: the mini suite's 100 training images of 64 × 64.
RECIPE_IMAGES = 100
RECIPE_SIDE = 64
#: The longest derived run and the largest budget: the paper's 100K steps and 550,000 Gaussians.
MAX_ITERATIONS = 100_000
MAX_GAUSSIANS = 550_000


@dataclass(frozen=True)
class SceneFacts:
    """What a derived preset is computed from: the number of training images and the size (px) they
    are trained at."""

    train_images: int
    width: int
    height: int

    def __post_init__(self) -> None:
        if self.train_images < 1 or self.width < 1 or self.height < 1:
            raise ValueError(f"a scene needs training images of positive size, not {self}")


@dataclass(frozen=True)
class DerivedPreset:
    """Config overrides for one scene (``values``) and, for each, why
    (``reasons``, one short sentence)."""

    recipe: str
    values: Mapping[str, Any]
    reasons: Mapping[str, str]

    @property
    def kept(self) -> list[str]:
        """The recipe's fields taken as they are (no reason of their own)."""
        return [name for name in self.values if name not in self.reasons]


def derive_preset(
    recipe_name: str, recipe: Mapping[str, Any], facts: SceneFacts, iterations: int | None = None
) -> DerivedPreset:
    """The method's small-scene ``recipe`` (its preset named ``recipe_name``) scaled to a scene.

    ``iterations``: the length asked for (``--iterations``, a user suite's ``iterations``), else
    derived from the number of training images. Fields the recipe does not hold (a method without a
    light-view pass) are not derived.
    """
    values = dict(recipe)
    reasons: dict[str, str] = {}
    base_steps = int(recipe["iterations"])
    if iterations is None:
        derived = min(
            MAX_ITERATIONS,
            max(base_steps, 100 * math.ceil(base_steps * facts.train_images / RECIPE_IMAGES / 100)),
        )
        values["iterations"] = derived
        reasons["iterations"] = (
            f"the {recipe_name} recipe's {base_steps} steps per {RECIPE_IMAGES} training "
            f"images, for {facts.train_images} (at least {base_steps}, at most "
            f"{MAX_ITERATIONS})"
        )
    else:
        values["iterations"] = int(iterations)
        reasons["iterations"] = "as asked"
    reference = int(recipe.get("reference_iterations", base_steps))
    reasons["reference_iterations"] = (
        f"the {recipe_name} recipe's: its windows and decays scale by iterations / "
        f"{reference} (with floors in short runs)"
    )
    area = max(1.0, facts.width * facts.height / RECIPE_SIDE**2)
    size = f"{facts.width}x{facts.height}"
    if "max_gaussians" in recipe:
        budget = min(MAX_GAUSSIANS, round(int(recipe["max_gaussians"]) * area))
        values["max_gaussians"] = budget
        reasons["max_gaussians"] = (
            f"the {recipe_name} recipe's {recipe['max_gaussians']} at {RECIPE_SIDE}², "
            f"× the pixel count of {size} (at least 1×, at most {MAX_GAUSSIANS})"
        )
        if "num_init_gaussians" in recipe:
            values["num_init_gaussians"] = max(
                1, round(recipe["num_init_gaussians"] * budget / recipe["max_gaussians"])
            )
            reasons["num_init_gaussians"] = (
                f"the {recipe_name} recipe's share of the budget "
                f"({recipe['num_init_gaussians']} of {recipe['max_gaussians']})"
            )
    if "shadow_resolution" in recipe:
        scale = max(1.0, max(facts.width, facts.height) / RECIPE_SIDE)
        values["shadow_resolution"] = round(int(recipe["shadow_resolution"]) * scale)
        reasons["shadow_resolution"] = (
            f"the {recipe_name} recipe's {recipe['shadow_resolution']} px at "
            f"{RECIPE_SIDE}², × the longer side of {size} (at least 1×)"
        )
    for name in ("refine_camera", "refine_light"):
        if name in recipe:
            reasons[name] = (
                "off: known poses and lights unless asked (--variant nrhints refines them)"
            )
    if "test_pose_fitting" in recipe:
        reasons["test_pose_fitting"] = "none: scored at the given test poses"
    return DerivedPreset(recipe=recipe_name, values=values, reasons=reasons)
