"""Paper-scale stand-ins: a rendered scene per real suite, in that suite's format, image size and
image count.

They exist to measure what a paper-scale run costs (time per step, memory) on a machine without the
real data; they are not quality references (few samples per pixel, one of the built-in recipes). The
sizes and counts are the paper's (§5 and appendix of the SSD-GS paper):

* ``nrhints``: real captures, 500–1500 training and 45–200 test images, four scenes at 512², three
  at 1024² (the stand-in takes the middle of the range at the more common 512²: 1000 / 100);
* ``gs3``: 2000 training and 400 test images at 512² (white background, HDR converted to gamma 2.2);
* ``sssgs``: the public down-scaled release, 500 training and 500 test images at 256².

`ensure_standin` renders one into ``$XDG_CACHE_HOME/olatbench/standins/<suite>-<train>`` on first
use (a folder per training-image count, so a quick run with fewer images does not replace the full
one) and reuses it after; the render goes to a temporary sibling that is renamed into place, so an
interruption leaves nothing half-made.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from olatbench.datasets.synth.recipe import RECIPES


@dataclass(frozen=True)
class Standin:
    """How to render the stand-in of one suite: a built-in ``recipe`` written in ``format`` at
    ``resolution`` (square, pixels) with ``train`` / ``test`` images and ``spp`` samples per
    pixel."""

    recipe: str
    format: str
    resolution: int
    train: int
    test: int
    spp: int = 4


STANDINS: dict[str, Standin] = {
    "nrhints": Standin(
        recipe="diffuse_shadow", format="nrhints", resolution=512, train=1000, test=100
    ),
    "gs3": Standin(recipe="aniso_metal", format="gs3", resolution=512, train=2000, test=400),
    "sssgs": Standin(recipe="translucent", format="sssgs", resolution=256, train=500, test=500),
}


def standin_root() -> Path:
    """``$XDG_CACHE_HOME/olatbench/standins`` (default ``~/.cache/olatbench/standins``)."""
    cache = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(cache) / "olatbench" / "standins"


def ensure_standin(
    suite: str, train: int | None = None, root: Path | None = None, progress: bool = True
) -> Path:
    """The stand-in scene folder of ``suite`` (rendered on first use); ``train`` overrides the
    training-image count (test images scale with it, at least one)."""
    from olatbench.datasets.synth.generate import generate

    if suite not in STANDINS:
        raise KeyError(f"no stand-in for suite '{suite}'; stand-ins: {', '.join(STANDINS)}")
    standin = STANDINS[suite]
    train = standin.train if train is None else int(train)
    test = max(1, round(standin.test * train / standin.train))
    root = standin_root() if root is None else Path(root)
    final = root / f"{suite}-{train}"
    if (final / "synth.json").is_file():
        return final
    partial = root / f".{suite}-{train}.partial"
    shutil.rmtree(partial, ignore_errors=True)
    recipe = RECIPES[standin.recipe].with_overrides(
        resolution=(standin.resolution, standin.resolution), spp=standin.spp, train=train, test=test
    )
    generate(recipe, partial, standin.format, progress=progress, geometry=False)
    os.replace(partial, final)
    return final
