"""Interleaved test-view fitting: the official SSD-GS real-data protocol
(``test_pose_fitting="interleaved"``).

The official training loop alternates epochs: after every pass over the training views comes one
pass over the *test* views (in a random order, the iteration counter standing still) in which only
those views' camera-pose and light-position offsets are updated — the model's parameters get no
update and densification sees nothing — and the scored test images are rendered with the fitted
offsets. `InterleavedFit` holds those offsets and runs one such pass; SSD-GS calls it when a
training epoch has just ended and applies the offsets when it renders a test view. SSD-GS's
evaluation protocol (`olatbench.methods.ssdgs.evaluation`) is what the runner sees of it.

Each test view owns its own zero-initialised SO3×R3 pose delta and light offset (`PoseRefinement` /
`LightRefinement` of one view), all in one Adam (eps 1e-15): as in the official code, where every
camera holds its own parameters, a view not rendered in a step has no gradient and its offsets do
not move. The rates are the training refinement's at the current step once that refinement has
started (``refine_from``), and 0 before. As in the official code, the test passes run from the first
epoch on and Adam steps every view's offsets in each of them, also while their rate is 0: the
official ``scene.optimizer`` steps every camera it renders (train.py:103-111, 196-203) with its
rates held at 0 until ``train_cam_freeze_step`` / ``train_pl_freeze_step``
(scene/__init__.py:137-151), so Adam's moments and step count are warm when a rate opens (5K / 15K)
while the offsets stay exactly zero until then. Gradients are taken with respect to the offsets
alone.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from torch import nn

from olatbench.gaussians.optim import make_adam
from olatbench.gaussians.refinement import LightRefinement, PoseRefinement
from olatbench.methods.base import Views
from olatbench.methods.training import LazyScalar, TrainingViews

if TYPE_CHECKING:
    from olatbench.datasets.records import Camera, PointLight

#: ``(test view index, refined w2c (4, 4), refined light position (3,)) -> training loss`` of that
#: view.
ViewLoss = Callable[[int, torch.Tensor, torch.Tensor], torch.Tensor]


def view_key(camera: Camera, light: PointLight) -> bytes:
    """Exact identity of a (pose, light position) pair, to recognise a training or test view at
    render time."""
    return (
        np.asarray(camera.c2w, dtype=np.float64).tobytes()
        + np.asarray(light.position, dtype=np.float64).tobytes()
    )


class InterleavedFit:
    """Per-test-view pose and light offsets, their optimiser and the random order of the test
    passes.

    ``views``: the test views as tensors (`TrainingViews`); ``keys``: view key (pose and light
    bytes, as SSD-GS recognises views) -> index. ``config`` supplies ``refine_camera`` /
    ``refine_light``.
    """

    def __init__(self, test: Views, config: Any, device: torch.device, seed: int) -> None:
        self.views = TrainingViews(test, device, seed)
        self.poses = (
            nn.ModuleList(PoseRefinement(1, device) for _ in range(len(test)))
            if config.refine_camera
            else None
        )
        self.lights = (
            nn.ModuleList(LightRefinement(1, device) for _ in range(len(test)))
            if config.refine_light
            else None
        )
        groups = []
        if self.poses is not None:
            groups.append({"params": [p.tangents for p in self.poses], "name": "camera", "lr": 0.0})
        if self.lights is not None:
            groups.append({"params": [p.offsets for p in self.lights], "name": "light", "lr": 0.0})
        self.optimizer = make_adam(groups)
        self.generator = torch.Generator().manual_seed(seed + 1)
        self.keys = {
            view_key(c, lt): i
            for i, (c, lt) in enumerate(zip(test.cameras, test.lights, strict=True))
        }

    def __len__(self) -> int:
        return len(self.views)

    def _active(self, refine_from: Mapping[str, int], step: int) -> dict[str, bool]:
        return {
            "camera": self.poses is not None and step >= refine_from["camera"],
            "light": self.lights is not None and step >= refine_from["light"],
        }

    def apply(
        self,
        index: int,
        w2c: torch.Tensor,
        position: torch.Tensor,
        refine_from: Mapping[str, int],
        step: int,
        every: bool = False,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Test view ``index``'s fitted w2c (4, 4) and light position (3,) at ``step`` (offsets that
        have not started yet are not applied, unless ``every``: they are still zero then, and take
        part in the graph)."""
        active = self._active(refine_from, step)
        if active["camera"] or (every and self.poses is not None):
            w2c = self.poses[index].apply(0, w2c)
        if active["light"] or (every and self.lights is not None):
            position = self.lights[index].apply(0, position)
        return w2c, position

    def deltas(
        self, index: int, refine_from: Mapping[str, int], step: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """Test view ``index``'s applied camera-space delta (4, 4) and light shift (3,), float64."""
        active = self._active(refine_from, step)
        with torch.no_grad():
            delta = (
                self.poses[index].delta(0).double().cpu().numpy() if active["camera"] else np.eye(4)
            )
            shift = (
                self.lights[index].offsets[0].double().cpu().numpy()
                if active["light"]
                else np.zeros(3)
            )
        return delta, shift

    def epoch(
        self,
        view_loss: ViewLoss,
        rates: Mapping[str, float],
        refine_from: Mapping[str, int],
        step: int,
    ) -> LazyScalar | None:
        """One pass over the test views in a fresh random order, one Adam step of every view's
        offsets: at the training ``rates`` of ``step`` for the offsets whose refinement has started,
        at rate 0 (moments only) for the others (module docstring); returns the mean loss (a
        `LazyScalar`: read when the runner logs it), or None when nothing is refined."""
        if self.poses is None and self.lights is None:
            return None
        active = self._active(refine_from, step)
        for group in self.optimizer.param_groups:
            group["lr"] = rates[group["name"]] if active[group["name"]] else 0.0
        views, losses = self.views, []
        for index in torch.randperm(len(self), generator=self.generator, device="cpu").tolist():
            params = ([self.poses[index].tangents] if self.poses is not None else []) + (
                [self.lights[index].offsets] if self.lights is not None else []
            )
            with torch.enable_grad():
                w2c, position = self.apply(
                    index,
                    views.w2cs[index],
                    views.light_positions[index],
                    refine_from,
                    step,
                    every=True,
                )
                loss = view_loss(index, w2c, position)
                grads = torch.autograd.grad(loss, params)
            for param, grad in zip(params, grads, strict=True):
                param.grad = grad
            self.optimizer.step()
            self.optimizer.zero_grad(set_to_none=True)
            losses.append(loss.detach())
        # read when logged
        return LazyScalar(lambda: sum(float(loss) for loss in losses) / len(losses))

    def state_dict(self) -> dict[str, Any]:
        """Offsets, optimiser state and the order generator (tensors and plain values, for
        checkpoints)."""
        return {
            "poses": [p.tangents.detach().clone() for p in self.poses]
            if self.poses is not None
            else [],
            "lights": [p.offsets.detach().clone() for p in self.lights]
            if self.lights is not None
            else [],
            "optimizer": self.optimizer.state_dict(),
            "generator": self.generator.get_state(),
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        with torch.no_grad():
            for module, value in zip(self.poses or [], state["poses"], strict=True):
                module.tangents.copy_(value)
            for module, value in zip(self.lights or [], state["lights"], strict=True):
                module.offsets.copy_(value)
        self.optimizer.load_state_dict(state["optimizer"])
        self.generator.set_state(state["generator"])


__all__ = ["InterleavedFit", "ViewLoss", "view_key"]
