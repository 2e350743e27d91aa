"""The host synchronisations a training step on a GPU is allowed, named where the code makes them.

On a GPU, reading a value the device computed (``.item()``, ``float(t)``, ``int(t)``, ``.tolist()``,
``.cpu()``), an op whose output size depends on values (``nonzero``, boolean-mask indexing,
``repeat_interleave`` without ``output_size``, ``bincount``, ``unique``) and a blocking copy between
host and device each stop the host until the device has caught up. A step should make none, except
where the host must know a value to go on; each such place wraps the read in
``with allowed_host_sync(NAME):`` with a NAME of `ALLOWANCES`, which also bounds how many syncs one
use of the block may make. The fake-CUDA dry run (`olatbench.gaussians.fake_cuda`) finds every sync
of a step and counts one inside such a block against that bound; any other is a finding. Outside a
dry run the block only sets a context variable.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass


@dataclass(frozen=True)
class Allowance:
    """A named reason to synchronise: ``limit`` syncs per use of its block (None: no bound), and
    why."""

    name: str
    limit: int | None
    reason: str


ALLOWANCES: dict[str, Allowance] = {
    a.name: a
    for a in (
        Allowance(
            "tile-intersections",
            1,
            "one per rasterization pass: the length of its tile-intersection list, needed to "
            "allocate it (gsplat's own isect_tiles reads cum_tiles_per_gauss[-1].item() for the "
            "same reason)",
        ),
        Allowance(
            "light-pass-entries",
            1,
            "one per light-view pass: its per-tile (pair, pixel) entry counts and list offsets, "
            "copied once to plan its chunks (a second list, of pixels, that the pass sizes after "
            "binning)",
        ),
        Allowance(
            "logging",
            None,
            "the runner reading a step's scalars, only at its logging interval "
            "(bench.execute.read_scalars)",
        ),
        Allowance(
            "density-control",
            None,
            "density control resizing the model at its interval (every densify_interval steps in "
            "its window, and opacity resets): the new Gaussian count is a value the device "
            "computed",
        ),
    )
}


@dataclass
class Use:
    """One entry into an allowance's block; ``syncs`` counts the syncs a dry run saw inside it."""

    allowance: Allowance
    syncs: int = 0


_current: ContextVar[Use | None] = ContextVar("olatbench_allowed_host_sync", default=None)


@contextmanager
def allowed_host_sync(name: str) -> Iterator[None]:
    """Mark the enclosed code as a use of allowance ``name`` (a key of `ALLOWANCES`)."""
    token = _current.set(Use(ALLOWANCES[name]))
    try:
        yield
    finally:
        _current.reset(token)


def current_use() -> Use | None:
    """The innermost allowance block being executed, or None."""
    return _current.get()


__all__ = ["ALLOWANCES", "Allowance", "Use", "allowed_host_sync", "current_use"]
