"""CPU stand-ins for the CUDA-only modules of the authors' code, for official jobs run with ``--code device=cpu``.

The authors' SSD-GS (26e4251) and GS³ (83c8daa) need CUDA only through ``gsplat`` (1.1.1), their
``diff_gaussian_rasterization_light``, ``tinycudann``, ``simple_knn`` and ``.cuda()``/``torch.cuda`` calls; their
``render.py`` also imports ``torchvision`` for ``save_image``. In a ``device=cpu`` job `job_environment` puts the
folder `SITE` first on the commands' ``PYTHONPATH`` (and olatbench's own folder after it), so that those names
import these stand-ins and its ``sitecustomize`` installs the device shim (`device`); nothing is written into the
user's checkout, and nothing of this is importable under those names anywhere else.

==============================================  ==============================================================
real module                                     stand-in (this package)
==============================================  ==============================================================
``gsplat.rasterization``                        `rasterization` (olatbench's projection and C++ rasterizer)
``diff_gaussian_rasterization_light``           `light` (forward.cu per pinned commit; C++ per-pixel loop)
``tinycudann.Encoding`` / ``Network``           `tcnn` (Frequency; FullyFusedMLP LeakyReLU/Sigmoid)
``simple_knn._C.distCUDA2``                     `knn` (olatbench's exact 3-nearest-neighbour search)
``torchvision.utils.save_image``                `save_image`
``torch.cuda`` / ``.cuda()`` / ``device=cuda``  `device` (installed by ``SITE/sitecustomize.py``)
==============================================  ==============================================================
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

SITE = Path(__file__).resolve().parent / "site"
OLATBENCH_ROOT = Path(__file__).resolve().parents[4]  # the folder holding the olatbench package
MODULES = ("gsplat", "diff_gaussian_rasterization_light", "tinycudann", "simple_knn", "torchvision", "sitecustomize")
VARIANT_VARIABLE = "OLATBENCH_STANDIN_LIGHT"  # names the forward.cu the light splat follows (light.VARIANTS)
# The forward.cu variant of the light splat per official method.
LIGHT_VARIANTS = {"ssdgs-official": "ssdgs-26e4251", "gs3-official": "gs3-83c8daa"}


def standins_for(method: str) -> tuple[str, ...]:
    """The modules replaced in a ``device=cpu`` job of ``method``: all of `MODULES` for the codes they were
    written for (SSD-GS, GS³), none for others (NRHints takes its own CPU path when ``torch.cuda`` reports no
    device, and would pick the tinycudann stand-in over its torch fallback)."""
    return MODULES if method in LIGHT_VARIANTS else ()


def job_environment(method: str, environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment variables a ``device=cpu`` command of ``method`` runs with (on top of ``environ``,
    default ``os.environ``): ``CUDA_VISIBLE_DEVICES`` empty (nothing may reach a GPU by another road); where
    `standins_for` names any, ``PYTHONPATH`` = `SITE`, olatbench's folder, then the inherited one, and the light
    splat's variant."""
    environ = os.environ if environ is None else environ
    env = {"CUDA_VISIBLE_DEVICES": ""}
    if standins_for(method):
        paths = [str(SITE), str(OLATBENCH_ROOT), *filter(None, environ.get("PYTHONPATH", "").split(os.pathsep))]
        env.update(PYTHONPATH=os.pathsep.join(paths), **{VARIANT_VARIABLE: LIGHT_VARIANTS[method]})
    return env


__all__ = ["LIGHT_VARIANTS", "MODULES", "OLATBENCH_ROOT", "SITE", "VARIANT_VARIABLE", "job_environment",
           "standins_for"]
