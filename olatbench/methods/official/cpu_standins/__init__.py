"""CPU stand-ins for the CUDA-only modules of the authors' code, for official jobs run with
``--code device=cpu``.

`job_environment` puts the folder `SITE` (SSD-GS, GS³; RNG with `RNG_MODULES`) or `NRHINTS_SITE`
first on the commands' ``PYTHONPATH``, so that the CUDA-only names the authors' scripts import load
these modules instead; nothing is written into the user's checkout. docs/official.md ("Running the
authors' code on the CPU") lists each real module, its stand-in and what differs.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

SITE = Path(__file__).resolve().parent / "site"  # SSD-GS, GS³
NRHINTS_SITE = Path(__file__).resolve().parent / "site_nrhints"  # NRHints: lpips, device_copy
OLATBENCH_ROOT = Path(__file__).resolve().parents[4]  # the folder holding the olatbench package
MODULES = (
    "gsplat",
    "diff_gaussian_rasterization_light",
    "tinycudann",
    "simple_knn",
    "torchvision",
    "sitecustomize",
)
# names the forward.cu the light splat follows (light.VARIANTS)
VARIANT_VARIABLE = "OLATBENCH_STANDIN_LIGHT"
# The forward.cu variant of the light splat per official method.
LIGHT_VARIANTS = {"ssdgs-official": "ssdgs-26e4251", "gs3-official": "gs3-83c8daa"}
NRHINTS_MODULES = ("lpips", "sitecustomize")
RNG_MODULES = (
    "diff_gaussian_rasterization",
    "diff_gaussian_rasterization_orthographic",
    "simple_knn",
    "torchvision",
    "torchmetrics",
    "sitecustomize",
)
# Per official method: the folder put first on PYTHONPATH and the modules it replaces
# (methods not named: none).
SITES: dict[str, tuple[Path, tuple[str, ...]]] = {
    "ssdgs-official": (SITE, MODULES),
    "gs3-official": (SITE, MODULES),
    "nrhints-official": (NRHINTS_SITE, NRHINTS_MODULES),
    "rng-official": (SITE, RNG_MODULES),
}


def standins_for(method: str) -> tuple[str, ...]:
    """The modules replaced in a ``device=cpu`` job of ``method`` (`SITES`): all of `MODULES` for
    the codes they were written for (SSD-GS, GS³); ``lpips`` and the ``sitecustomize`` of
    `device_copy` for NRHints (which takes its own CPU path when ``torch.cuda`` reports no device; a
    tinycudann stand-in would turn its optional import on); `RNG_MODULES` for RNG; none for
    others."""
    return SITES[method][1] if method in SITES else ()


def site_for(method: str) -> Path | None:
    """The stand-in folder of a ``device=cpu`` job of ``method`` (`SITE`, `NRHINTS_SITE`), or
    None."""
    return SITES[method][0] if method in SITES else None


def job_environment(method: str, environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment variables a ``device=cpu`` command of ``method`` runs with (on top of
    ``environ``, default ``os.environ``): ``CUDA_VISIBLE_DEVICES`` empty (nothing may reach a GPU by
    another road); where the method has stand-ins, ``PYTHONPATH`` = its folder (`site_for`),
    olatbench's folder, then the inherited one; for SSD-GS and GS³ the light splat's variant."""
    environ = os.environ if environ is None else environ
    env = {"CUDA_VISIBLE_DEVICES": ""}
    site = site_for(method)
    if site is not None:
        paths = [
            str(site),
            str(OLATBENCH_ROOT),
            *filter(None, environ.get("PYTHONPATH", "").split(os.pathsep)),
        ]
        env["PYTHONPATH"] = os.pathsep.join(paths)
    if method in LIGHT_VARIANTS:
        env[VARIANT_VARIABLE] = LIGHT_VARIANTS[method]
    return env


__all__ = [
    "LIGHT_VARIANTS",
    "MODULES",
    "NRHINTS_MODULES",
    "NRHINTS_SITE",
    "OLATBENCH_ROOT",
    "RNG_MODULES",
    "SITE",
    "SITES",
    "VARIANT_VARIABLE",
    "job_environment",
    "site_for",
    "standins_for",
]
