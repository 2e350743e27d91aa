"""CPU stand-ins for the CUDA-only modules of the authors' code, for official jobs run with ``--code device=cpu``.

The authors' SSD-GS (26e4251) and GS³ (83c8daa) need CUDA only through ``gsplat`` (1.1.1), their
``diff_gaussian_rasterization_light``, ``tinycudann``, ``simple_knn`` and ``.cuda()``/``torch.cuda`` calls; their
``render.py`` also imports ``torchvision`` for ``save_image``. In a ``device=cpu`` job `job_environment` puts the
folder `SITE` first on the commands' ``PYTHONPATH`` (and olatbench's own folder after it), so that those names
import these stand-ins and its ``sitecustomize`` installs the device shim (`device`); nothing is written into the
user's checkout, and nothing of this is importable under those names anywhere else.

RNG (4e8748e) needs CUDA through its two rasterizer forks (``diff_gaussian_rasterization`` with a low-pass radius
and depth/alpha outputs, ``diff_gaussian_rasterization_orthographic``), ``simple_knn`` and ``.cuda()`` calls;
its ``render.py`` imports ``torchvision`` (``save_image``) and ``torchmetrics.functional.image`` (PSNR, SSIM, LPIPS
for a metrics.txt). Its jobs get `SITE` with `RNG_MODULES` (the other methods' modules there are not imported by
its code).

NRHints (291800d) runs on the CPU by itself: it picks the CPU when ``torch.cuda`` reports no device
(``trainer/trainer.py:48``), its networks are torch (frequency encodings, ``nn.Linear``), and ``tinycudann`` is
only an optional import for a ``HashEncoding`` its configs do not build (``fields/encodings.py:31-36, 237``). But
``utils/metrics.py:4`` imports ``lpips``, which needs torchvision and downloads AlexNet, and its test-view
rendering keeps every chunk's autograd graph on the CPU (`device_copy`): its jobs get `NRHINTS_SITE` instead,
which holds only ``lpips`` (`lpips`) and a ``sitecustomize`` installing `device_copy` — none of the other
stand-ins and not the CUDA device shim, so that its own CPU path and optional-import fallbacks stay as written.

==============================================  ==============================================================
real module                                     stand-in (this package)
==============================================  ==============================================================
``gsplat.rasterization``                        `rasterization` (olatbench's projection and C++ rasterizer)
``diff_gaussian_rasterization_light``           `light` (forward.cu per pinned commit; C++ per-pixel loop)
``tinycudann.Encoding`` / ``Network``           `tcnn` (Frequency; FullyFusedMLP LeakyReLU/Sigmoid)
``simple_knn._C.distCUDA2``                     `knn` (olatbench's exact 3-nearest-neighbour search)
``diff_gaussian_rasterization`` (RNG's fork)    `rng_rasterizer` (forward.cu/__init__.py of RNG's fork)
``diff_gaussian_rasterization_orthographic``    `rng_orthographic` (RNG; forward only, as the fork)
``torchmetrics.functional.image`` (RNG only)    `torchmetrics_image` (PSNR, SSIM, LPIPS at render.py's defaults)
``torchvision.utils.save_image``                `save_image`
``torch.cuda`` / ``.cuda()`` / ``device=cuda``  `device` (installed by ``SITE/sitecustomize.py``)
``lpips.LPIPS(net="alex")`` (NRHints only)      `lpips` (olatbench's LPIPSNet, installed weights), in `NRHINTS_SITE`
``Tensor.to`` under ``no_grad`` (NRHints only)  `device_copy` (drops the graph as a GPU copy does), by
                                                ``NRHINTS_SITE/sitecustomize.py``
==============================================  ==============================================================
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

SITE = Path(__file__).resolve().parent / "site"  # SSD-GS, GS³
NRHINTS_SITE = Path(__file__).resolve().parent / "site_nrhints"  # NRHints: lpips, device_copy
OLATBENCH_ROOT = Path(__file__).resolve().parents[4]  # the folder holding the olatbench package
MODULES = ("gsplat", "diff_gaussian_rasterization_light", "tinycudann", "simple_knn", "torchvision", "sitecustomize")
VARIANT_VARIABLE = "OLATBENCH_STANDIN_LIGHT"  # names the forward.cu the light splat follows (light.VARIANTS)
# The forward.cu variant of the light splat per official method.
LIGHT_VARIANTS = {"ssdgs-official": "ssdgs-26e4251", "gs3-official": "gs3-83c8daa"}
NRHINTS_MODULES = ("lpips", "sitecustomize")
RNG_MODULES = ("diff_gaussian_rasterization", "diff_gaussian_rasterization_orthographic", "simple_knn", "torchvision",
               "torchmetrics", "sitecustomize")
# Per official method: the folder put first on PYTHONPATH and the modules it replaces (methods not named: none).
SITES: dict[str, tuple[Path, tuple[str, ...]]] = {
    "ssdgs-official": (SITE, MODULES), "gs3-official": (SITE, MODULES),
    "nrhints-official": (NRHINTS_SITE, NRHINTS_MODULES), "rng-official": (SITE, RNG_MODULES)}


def standins_for(method: str) -> tuple[str, ...]:
    """The modules replaced in a ``device=cpu`` job of ``method`` (`SITES`): all of `MODULES` for the codes they
    were written for (SSD-GS, GS³); ``lpips`` and the ``sitecustomize`` of `device_copy` for NRHints (which takes
    its own CPU path when ``torch.cuda`` reports no device; a tinycudann stand-in would turn its optional import
    on); `RNG_MODULES` for RNG; none for others."""
    return SITES[method][1] if method in SITES else ()


def site_for(method: str) -> Path | None:
    """The stand-in folder of a ``device=cpu`` job of ``method`` (`SITE`, `NRHINTS_SITE`), or None."""
    return SITES[method][0] if method in SITES else None


def job_environment(method: str, environ: Mapping[str, str] | None = None) -> dict[str, str]:
    """The environment variables a ``device=cpu`` command of ``method`` runs with (on top of ``environ``,
    default ``os.environ``): ``CUDA_VISIBLE_DEVICES`` empty (nothing may reach a GPU by another road); where
    the method has stand-ins, ``PYTHONPATH`` = its folder (`site_for`), olatbench's folder, then the inherited
    one; for SSD-GS and GS³ the light splat's variant."""
    environ = os.environ if environ is None else environ
    env = {"CUDA_VISIBLE_DEVICES": ""}
    site = site_for(method)
    if site is not None:
        paths = [str(site), str(OLATBENCH_ROOT), *filter(None, environ.get("PYTHONPATH", "").split(os.pathsep))]
        env["PYTHONPATH"] = os.pathsep.join(paths)
    if method in LIGHT_VARIANTS:
        env[VARIANT_VARIABLE] = LIGHT_VARIANTS[method]
    return env


__all__ = ["LIGHT_VARIANTS", "MODULES", "NRHINTS_MODULES", "NRHINTS_SITE", "OLATBENCH_ROOT", "RNG_MODULES", "SITE",
           "SITES", "VARIANT_VARIABLE", "job_environment", "site_for", "standins_for"]
