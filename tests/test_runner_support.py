"""A trivial, fast, bit-exactly resumable method and tiny suites for the runner tests.

Importable by worker processes (spawned pools, submitit, subprocesses) with ``tests/`` on
PYTHONPATH. The method learns one image (per-pixel logits) plus a per-light gain with Adam, sampling
a training view with torch's global generator and adding numpy noise, so a resume is only exact when
the runner restores both RNG states and the optimiser state.
"""

from __future__ import annotations

import os
import signal
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch

from olatbench.datasets.suites import Suite
from olatbench.methods.base import Method, Views
from olatbench.methods.registry import register
from olatbench.metrics.protocols import Protocol, protocol_names, register_protocol

TESTS = Path(__file__).resolve().parent
# seconds per step of every trivial job of a process and its workers,
STEP_SLEEP_ENV = "OLATBENCH_TEST_STEP_SLEEP"
# kept out of the config (so out of the job id): a slowed first attempt and its rerun are the same
# job


@dataclass
class TrivialConfig:
    iterations: int = 20
    lr: float = 0.1
    noise: float = 0.01
    fail_at_step: int = -1  # raise in train_step at this step (failure-isolation tests)
    step_sleep: float = 0.0  # seconds per step (kill tests)
    interrupt_at_step: int = -1  # raise KeyboardInterrupt at this step (an in-process Ctrl-C)
    # end the whole process at this step, as `die_by` says (a worker killed from outside)
    die_at_step: int = -1
    # a signal the process sends itself (SIGKILL, SIGSEGV, ...) or "exit" (os._exit(3))
    die_by: str = "SIGKILL"


class TrivialMethod(Method):
    """Mean-image regression: ``rgb = sigmoid(logits) * gain``; components ``shadow`` and
    ``diffuse``."""

    name = "trivial"
    config_class = TrivialConfig
    description = "Test method: learns one image with Adam."
    presets: ClassVar[dict[str, dict[str, Any]]] = {
        "tiny": {"iterations": 12},
        "fails": {"fail_at_step": 3},
        **{f"ablation-{letter}": {"lr": 0.01 * (i + 1)} for i, letter in enumerate("ABCDEF")},
        **{f"schedule-{letter}": {"noise": 0.001 * (i + 1)} for i, letter in enumerate("HIJK")},
        "shadow-on-sss": {"noise": 0.5},
    }
    ablations: ClassVar[dict[str, tuple[str, ...]]] = {
        "components": tuple(f"ablation-{letter}" for letter in "ABCDEF"),
        "schedule": tuple(f"schedule-{letter}" for letter in "HIJK"),
        "shadow-on-sss": ("default", "shadow-on-sss"),
    }

    def setup(self, train: Views, device, seed: int) -> None:
        self.device = torch.device(device)
        self.images = torch.from_numpy(train.images).to(self.device)
        height, width = train.images.shape[1:3]
        self.logits = torch.zeros(height, width, 3, device=self.device, requires_grad=True)
        self.gain = torch.ones(1, device=self.device, requires_grad=True)
        self.optimizer = torch.optim.Adam([self.logits, self.gain], lr=self.config.lr)

    def _image(self) -> torch.Tensor:
        return torch.sigmoid(self.logits) * self.gain

    def train_step(self, step: int) -> dict[str, float]:
        if step == self.config.fail_at_step:
            raise RuntimeError(f"injected failure at step {step}")
        if step == self.config.interrupt_at_step:
            raise KeyboardInterrupt
        if step == self.config.die_at_step:
            if self.config.die_by == "exit":
                os._exit(3)
            os.kill(os.getpid(), getattr(signal, self.config.die_by))
        sleep = self.config.step_sleep or float(os.environ.get(STEP_SLEEP_ENV, 0))
        if sleep:
            time.sleep(sleep)
        index = int(torch.randint(len(self.images), (1,)).item())
        noise = torch.from_numpy(
            np.random.normal(0.0, self.config.noise, self.images.shape[1:]).astype(np.float32)
        )
        loss = torch.mean((self._image() - self.images[index] - noise.to(self.device)) ** 2)
        self.optimizer.zero_grad()
        loss.backward()
        self.optimizer.step()
        loss = loss.detach()
        return {"loss": float(loss), "psnr": float(-10 * torch.log10(loss))}

    def render(self, camera, light) -> dict[str, torch.Tensor]:
        image = self._image().detach().clamp(0, 1)
        if image.shape[:2] != (camera.height, camera.width):
            image = torch.nn.functional.interpolate(
                image.permute(2, 0, 1)[None],
                (camera.height, camera.width),
                mode="bilinear",
                align_corners=False,
            )[0].permute(1, 2, 0)
        return {"rgb": image, "diffuse": image * 0.5, "shadow": image.mean(dim=2)}

    def state_dict(self) -> dict:
        return {
            "logits": self.logits.detach().clone(),
            "gain": self.gain.detach().clone(),
            "optimizer": self.optimizer.state_dict(),
        }

    def load_state_dict(self, state: dict) -> None:
        with torch.no_grad():
            self.logits.copy_(state["logits"])
            self.gain.copy_(state["gain"])
        self.optimizer.load_state_dict(state["optimizer"])

    @property
    def num_gaussians(self) -> int | None:
        return int(self.logits.shape[0] * self.logits.shape[1])


register("trivial", TrivialMethod)


class _FastProtocol(Protocol):
    """olatbench-v1 without the LPIPS networks (reported as None): keeps runner tests fast."""

    def lpips_batch(self, pred, gt, mask, device):
        return {net: [None] * pred.shape[0] for net in self.lpips_nets}


FAST_PROTOCOL = "test-fast"
if FAST_PROTOCOL not in protocol_names():
    register_protocol(
        _FastProtocol(
            id=FAST_PROTOCOL,
            version=1,
            description="test protocol without LPIPS",
            reproduces="nothing",
            lpips_nets=("alex",),
            lpips_primary="alex",
        )
    )


def tiny_suite(
    name: str = "tiny",
    scenes: tuple[str, ...] = ("Alpha", "Beta"),
    iterations: int = 20,
    protocol: str = FAST_PROTOCOL,
) -> Suite:
    """An NRHints-format suite over folders written by `write_tiny_data`."""
    return Suite(
        name=name,
        format="nrhints",
        scenes=scenes,
        aliases={s.lower(): s for s in scenes},
        iterations=iterations,
        protocol=protocol,
    )


def write_tiny_data(
    root: Path, scenes: tuple[str, ...] = ("Alpha", "Beta"), size: tuple[int, int] = (64, 48)
) -> Path:
    """One tiny NRHints tree per scene below ``root`` (4 train, 2 test views)."""
    from datasets_trees import write_nrhints_tree

    for index, scene in enumerate(scenes):
        write_nrhints_tree(Path(root) / scene, n_train=4, n_test=2, size=size, seed=index)
    return Path(root)
