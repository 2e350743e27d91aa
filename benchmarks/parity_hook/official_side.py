"""Runs the authors' unmodified SSD-GS ``train.py`` (26e4251; GS³ 83c8daa the same way) for
`benchmarks/parity.py` and records what the native side needs to follow it step by step; nothing
here changes what ``train.py`` computes. Line numbers below are SSD-GS's.

Usage (in the official environment, the checkout as working folder, olatbench's CPU stand-in folder
first on ``PYTHONPATH`` exactly as a ``device=cpu`` job has it)::

    python official_side.py OUT STEPS train.py ARG...

Before ``train.py`` runs, three of the authors' functions are wrapped at import time:

- ``GaussianModel.training_setup`` (``scene/gaussian_model.py:295``): after it, the initial state —
  every per-Gaussian tensor, the ASG lobes, the SSS network's and the shadow network's weights — is
  saved to ``OUT/initial.pt`` (`gaussian_state`);
- ``gaussian_renderer.render``, which ``train.py:135`` calls once per iteration: records the
  training view's ``image_name`` (the view ``viewpoint_stack.pop(randint(...))`` drew,
  ``train.py:116``); at call ``STEPS + 1`` (after ``STEPS`` optimizer updates) it saves the state to
  ``OUT/final.pt`` and ends the process; each iteration's render (3, H, W), before ``train.py``
  clips it, goes to ``OUT/renders.pt`` (STEPS, 3, H, W), and each view's image as the authors'
  loader made it (``original_image``, (3, H, W)) to ``OUT/targets.pt``; GS³'s render is the
  unshadowed image, so for GS³ also ``render · shadow + other_effects``, the image its ``train.py``
  trains after the shadow phase starts (GS³ ``train.py:131-135``), to ``OUT/composites.pt``;
- ``torch.utils.tensorboard.SummaryWriter``, which ``train.py:27-31`` imports when present: a
  recorder of the scalars ``training_report`` logs each iteration (``train.py:172, 260-261``: the
  loss and its L1 part).

``OUT/steps.json`` holds per iteration (from 1): the view's name, the loss and the L1 loss.
"""

from __future__ import annotations

import json
import os
import runpy
import sys
import types
from typing import Any, ClassVar

import torch

STATE_TENSORS = (
    "_xyz",
    "_scaling",
    "_rotation",
    "_opacity",
    "kd",
    "ks",
    "ksss",
    "alpha_asg",
    "local_q",
    "neural_material",
)  # those the model has (GS³ has no ksss)


def gaussian_state(gaussians: Any) -> dict[str, torch.Tensor]:
    """The authors' model as plain tensors (names as their attributes): per-Gaussian parameters, the
    ASG lobes (``asg_sigma``, ``asg_scales``, ``asg_rotation``), ``scatter.<state_dict key>`` of
    SSD-GS's SSS network, ``phasefunc.params`` of the shadow network and (GS³) ``other.params`` of
    the other-effects network (their flat tiny-cuda-nn ``params``)."""
    state = {
        name: getattr(gaussians, name).detach().clone()
        for name in STATE_TENSORS
        if isinstance(getattr(gaussians, name, None), torch.Tensor)
    }
    for name in ("asg_sigma", "asg_scales", "asg_rotation"):
        state[name] = getattr(gaussians.asg_func, name).detach().clone()
    if isinstance(getattr(gaussians, "scatter_mlp", None), torch.nn.Module):
        state.update(
            {
                f"scatter.{k}": v.detach().clone()
                for k, v in gaussians.scatter_mlp.state_dict().items()
            }
        )
    phase = gaussians.neural_phasefunc
    state.update(
        {f"phasefunc.{k}": v.detach().clone() for k, v in phase.shadow_func.state_dict().items()}
    )
    if hasattr(phase, "other_effects_func"):
        state.update(
            {
                f"other.{k}": v.detach().clone()
                for k, v in phase.other_effects_func.state_dict().items()
            }
        )
    return state


class _Recorder:
    """Stands in for tensorboard's ``SummaryWriter``: keeps the per-iteration scalars, ignores the
    rest."""

    scalars: ClassVar[dict[int, dict[str, float]]] = {}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def add_scalar(self, tag: str, value: Any, step: int) -> None:
        _Recorder.scalars.setdefault(int(step), {})[tag] = float(value)

    def __getattr__(self, name: str) -> Any:
        return lambda *args, **kwargs: None


def main(argv: list[str]) -> None:
    out, steps, script = argv[0], int(argv[1]), argv[2]
    os.makedirs(out, exist_ok=True)
    sys.path.insert(0, os.getcwd())  # the checkout, as `python train.py` would have it
    tensorboard = types.ModuleType("torch.utils.tensorboard")
    tensorboard.SummaryWriter = _Recorder
    sys.modules["torch.utils.tensorboard"] = tensorboard

    import gaussian_renderer
    from scene.gaussian_model import GaussianModel

    held: dict[str, Any] = {}
    views: list[str] = []
    renders: list[torch.Tensor] = []
    # GS³: the image train.py trains once the shadow phase is on
    composites: list[torch.Tensor] = []
    targets: dict[str, torch.Tensor] = {}
    setup, render = GaussianModel.training_setup, gaussian_renderer.render

    def training_setup(self: Any, training_args: Any) -> None:
        setup(self, training_args)
        held["gaussians"] = self
        torch.save(gaussian_state(self), os.path.join(out, "initial.pt"))

    def finish() -> None:
        torch.save(gaussian_state(held["gaussians"]), os.path.join(out, "final.pt"))
        records = [
            {
                "iteration": i + 1,
                "view": view,
                "loss": _Recorder.scalars.get(i + 1, {}).get("train_loss_patches/total_loss"),
                "l1": _Recorder.scalars.get(i + 1, {}).get("train_loss_patches/l1_loss"),
            }
            for i, view in enumerate(views[:steps])
        ]
        with open(os.path.join(out, "steps.json"), "w") as file:
            json.dump(records, file)
        torch.save(
            torch.stack(renders[:steps]) if renders else torch.zeros(0),
            os.path.join(out, "renders.pt"),
        )
        torch.save(targets, os.path.join(out, "targets.pt"))
        if composites:
            torch.save(torch.stack(composites[:steps]), os.path.join(out, "composites.pt"))

    def recorded_render(viewpoint_camera: Any, *args: Any, **kwargs: Any) -> Any:
        if len(views) == steps:
            finish()
            raise SystemExit(0)
        views.append(viewpoint_camera.image_name)
        targets[viewpoint_camera.image_name] = viewpoint_camera.original_image.detach().clone()
        package = render(viewpoint_camera, *args, **kwargs)
        renders.append(package["render"].detach().clone())
        # GS³ train.py:131-135: image * shadow + other_effects after the shadow phase
        if "other_effects" in package:
            composites.append(
                (package["render"] * package["shadow"] + package["other_effects"]).detach().clone()
            )
        return package

    GaussianModel.training_setup = training_setup
    gaussian_renderer.render = recorded_render
    sys.argv = [script, *argv[3:]]
    runpy.run_path(script, run_name="__main__")
    finish()  # train.py ended before STEPS + 1 iterations


if __name__ == "__main__":
    main(sys.argv[1:])
