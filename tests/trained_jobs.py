"""Tiny jobs (SSD-GS, 3DGS, GS³) trained through the runner in seconds, for tests that need a
finished job folder."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import test_runner_support as support

from olatbench.bench.execute import run_job
from olatbench.bench.plan import make_plan


def train_tiny(
    method: str, root: Path, iterations: int = 16, frame: str | None = None, **config: Any
) -> Path:
    """Train ``method`` (its mini preset, 300 Gaussians, ``config`` overrides) for ``iterations``
    steps on one tiny NRHints scene (4 train, 2 test views at 64×48) below ``root``, in the
    canonical frame fitted to its cameras (``frame="dataset"``: in the data's own); returns the
    finished job folder."""
    data = support.write_tiny_data(Path(root) / "data", scenes=("Alpha",))
    job = make_plan(
        method,
        support.tiny_suite(scenes=("Alpha",)),
        Path(root) / "runs",
        variants=["mini"],
        iterations=iterations,
        data_root=data,
        progress=False,
    )[0]
    job = dataclasses.replace(
        job, config={**job.config, "num_init_gaussians": 300, **config}, frame=frame or job.frame
    ).with_id()
    outcome = run_job(job, progress=False)
    assert outcome.status == "done", (Path(job.folder) / "error.txt").read_text()
    return Path(job.folder)


def train_tiny_ssdgs(root: Path, iterations: int = 16, **config: Any) -> Path:
    """`train_tiny` of SSD-GS with a 32² light view."""
    return train_tiny("ssdgs", root, iterations, **{"shadow_resolution": 32, **config})
