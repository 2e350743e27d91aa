"""Stand-in for torchvision in an official job with device=cpu: only
``torchvision.utils.save_image`` (what the authors' render.py and scene/__init__.py use); anything
else raises ImportError naming what is missing."""

from . import utils


def __getattr__(name):
    raise ImportError(
        f"torchvision stand-in (olatbench CPU): torchvision.{name} is not provided, only "
        "torchvision.utils.save_image / make_grid"
    )


__all__ = ["utils"]
