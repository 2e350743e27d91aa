"""Warnings that catch a ruined training run while it trains: the Gaussian count collapsing, or the
training PSNR staying below what an image of the background alone scores.

`RunHealth` watches the scalars a method's ``train_step`` returns (``num_gaussians``, ``psnr``); the
runner asks it at every checkpoint and at the end (`RunHealth.check`), logs each new warning once
and keeps them in the job folder's ``warnings.txt`` (one per line), which ``olatbench status``
shows. numpy only.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import numpy as np

from olatbench.atomic import write_text
from olatbench.metrics.decibels import psnr_from_mse

WARNINGS_FILE = "warnings.txt"
#: A count below this fraction of the initial one has collapsed.
COLLAPSE_FRACTION = 0.10
#: The training PSNR is judged on the mean of the last steps logged (a window this long), after this
#: fraction of the run (the first steps of any run are below the background's).
PSNR_WINDOW = 50
PSNR_FROM = 0.5

COLLAPSE_CAUSE = (
    "likely cause: opacity resets or pruning faster than the Gaussians can recover (a schedule "
    "shortened without floors, a custom opacity_reset_interval / densify_* setting), or Gaussians "
    "initialised where the cameras do not see them (init_radius)"
)
BACKGROUND_CAUSE = (
    "likely cause: the Gaussians are initialised away from the object (init_radius), the "
    "scene's background or colour space is not what the images hold, or its cameras / lights "
    "are in another convention (olatbench datasets validate DIR)"
)


def background_psnr(images: np.ndarray, background: np.ndarray) -> float:
    """PSNR (dB, peak 1) of an image of the background colour alone against ``images``
    ((N, H, W, 3) in [0, 1]): what a model that renders nothing scores."""
    colour = np.asarray(background, dtype=np.float64)
    total = sum(
        float(np.mean((np.asarray(image, dtype=np.float64) - colour) ** 2)) for image in images
    )
    mse = total / max(1, len(images))  # images of one size: the mean of the per-image means
    return psnr_from_mse(mse)


class RunHealth:
    """The health of one training run: fed the scalars of every logged step (`observe`), asked for
    warnings (`check`).

    ``initial_gaussians``: the count after set-up (None: the method has no Gaussians);
    ``floor_psnr``: the background-only image's PSNR (`background_psnr`; None: not checked);
    ``iterations``: the run's length.
    """

    def __init__(
        self, initial_gaussians: int | None, floor_psnr: float | None, iterations: int
    ) -> None:
        self.initial = initial_gaussians
        self.floor_psnr = floor_psnr
        self.iterations = iterations
        self.count: float | None = None
        self.psnr: deque[float] = deque(maxlen=PSNR_WINDOW)
        self.step = 0

    def observe(self, step: int, scalars: dict[str, float]) -> None:
        """Record one finished step (1-based) and its scalars."""
        self.step = step
        if "num_gaussians" in scalars:
            self.count = scalars["num_gaussians"]
        if "psnr" in scalars and np.isfinite(scalars["psnr"]):
            self.psnr.append(float(scalars["psnr"]))

    def check(self) -> list[str]:
        """The warnings that hold now, each one line ``kind: what happened; likely cause``."""
        found = []
        if (
            self.initial
            and self.count is not None
            and self.count < COLLAPSE_FRACTION * self.initial
        ):
            found.append(
                f"collapse: the Gaussian count collapsed from {self.initial} to {int(self.count)} "
                f"by step {self.step} (below {COLLAPSE_FRACTION:.0%} of the initial count); "
                f"{COLLAPSE_CAUSE}"
            )
        if (
            self.floor_psnr is not None
            and self.psnr
            and self.step >= PSNR_FROM * self.iterations
            and np.mean(self.psnr) < self.floor_psnr
        ):
            found.append(
                f"below background: the training PSNR ({np.mean(self.psnr):.2f} dB over the last "
                f"{len(self.psnr)} steps logged, at step {self.step}) is below the "
                f"{self.floor_psnr:.2f} dB of an image of the background alone: the model renders "
                f"less than nothing; {BACKGROUND_CAUSE}"
            )
        return found


def read_warnings(folder: str | Path) -> list[str]:
    """The warnings recorded in a job folder (none when it has no ``warnings.txt``)."""
    path = Path(folder) / WARNINGS_FILE
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except FileNotFoundError:
        return []
    return [line for line in text.splitlines() if line.strip()]


def record_warnings(folder: str | Path, warnings: list[str]) -> list[str]:
    """Add ``warnings`` of a kind not yet recorded to the folder's ``warnings.txt`` (atomically; the
    first of each kind is kept); returns the new ones."""
    known = read_warnings(folder)
    kinds = {line.partition(":")[0] for line in known}
    new = [line for line in warnings if line.partition(":")[0] not in kinds]
    if new:
        write_text(Path(folder) / WARNINGS_FILE, "\n".join(known + new) + "\n")
    return new
