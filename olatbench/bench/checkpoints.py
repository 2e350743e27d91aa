"""Training checkpoints: method state + step + RNG states, written atomically, loaded with
weights_only.

A checkpoint ``checkpoints/step_<step:08d>.pt`` holds ``step`` = the number of completed training
steps (the next step to run), the method's `state_dict`, the python/numpy/torch(/CUDA) RNG states,
the accumulated training seconds and the job id. Restoring all of them makes a resumed run take
exactly the path an uninterrupted run would have taken (for methods that keep all their
randomness in these generators or in their own state dict).
"""

from __future__ import annotations

import random
from pathlib import Path
from typing import Any

import numpy as np
import torch

from olatbench.atomic import atomic_path
from olatbench.bench.store import checkpoint_dir, list_checkpoints  # the folder layout (torch-free)

CHECKPOINT_FORMAT = 1


def seed_everything(seed: int) -> None:
    """Seed python's `random`, numpy's global generator and torch (all devices)."""
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


def rng_states() -> dict[str, Any]:
    """The global RNG states as tensors and plain values (loadable with ``weights_only=True``)."""
    version, internal, gauss = random.getstate()
    numpy_state = np.random.get_state(legacy=False)
    states: dict[str, Any] = {
        "python": {"version": version, "state": list(internal), "gauss": gauss},
        "numpy": {
            "key": torch.from_numpy(numpy_state["state"]["key"].astype(np.int64)),
            "pos": int(numpy_state["state"]["pos"]),
            "has_gauss": int(numpy_state["has_gauss"]),
            "gauss": float(numpy_state["gauss"]),
        },
        "torch": torch.get_rng_state(),
    }
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        states["cuda"] = torch.cuda.get_rng_state_all()
    return states


def restore_rng_states(states: dict[str, Any]) -> None:
    """Inverse of `rng_states`."""
    python = states["python"]
    random.setstate((python["version"], tuple(python["state"]), python["gauss"]))
    numpy = states["numpy"]
    np.random.set_state(
        {
            "bit_generator": "MT19937",
            "state": {"key": numpy["key"].numpy().astype(np.uint32), "pos": numpy["pos"]},
            "has_gauss": numpy["has_gauss"],
            "gauss": numpy["gauss"],
        }
    )
    torch.set_rng_state(states["torch"])
    if "cuda" in states and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(states["cuda"])


def save_checkpoint(
    folder: str | Path,
    step: int,
    method_state: dict[str, Any],
    job_id: str,
    train_seconds: float,
    keep: int = 2,
) -> Path:
    """Write ``checkpoints/step_<step>.pt`` atomically, then delete all but the newest ``keep``."""
    path = checkpoint_dir(folder) / f"step_{step:08d}.pt"
    payload = {
        "format": CHECKPOINT_FORMAT,
        "job_id": job_id,
        "step": int(step),
        "method": method_state,
        "rng": rng_states(),
        "train_seconds": float(train_seconds),
    }
    with atomic_path(path) as temporary, open(temporary, "wb", buffering=0) as handle:
        try:
            torch.save(payload, handle)  # unbuffered: a failed write is the OSError of its syscall
        # torch reports a failed write as "unexpected pos"; raise its cause
        except RuntimeError as error:
            # (full disk...), which atomic_path names as a WriteError
            if isinstance(error.__context__, OSError):
                raise error.__context__ from None
            raise
    prune_checkpoints(folder, keep)
    return path


def prune_checkpoints(folder: str | Path, keep: int) -> None:
    """Delete all but the newest ``keep`` (≥ 1) checkpoints."""
    for _, path in list_checkpoints(folder)[: -max(1, keep)]:
        path.unlink(missing_ok=True)


class CheckpointUnreadable(RuntimeError):
    """A checkpoint file that is no checkpoint of the job asked for: torch cannot load it
    (truncated, zero bytes, not a zip, an object ``weights_only`` refuses), or it is not a dict of
    this format with the payload's fields, or it belongs to another job. The message names the file
    and the reason."""


_PAYLOAD_FIELDS = {"step": int, "method": dict, "rng": dict, "train_seconds": float}


def load_checkpoint(path: str | Path, job_id: str) -> dict[str, Any]:
    """Load a checkpoint (``weights_only=True``) and check that it is one of this format, with its
    fields, belonging to ``job_id``; anything else is a `CheckpointUnreadable`."""
    path = Path(path)
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as error:
        reason = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        raise CheckpointUnreadable(
            f"{path}: cannot read checkpoint ({reason}); delete it or rerun with --force"
        ) from error
    if not isinstance(payload, dict):
        raise CheckpointUnreadable(f"{path}: not a checkpoint (holds a {type(payload).__name__})")
    if payload.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointUnreadable(
            f"{path}: checkpoint format {payload.get('format')!r} is not {CHECKPOINT_FORMAT}"
        )
    if payload.get("job_id") != job_id:
        raise CheckpointUnreadable(
            f"{path}: checkpoint of job {payload.get('job_id')} cannot resume job {job_id}; "
            "rerun with --force to start over"
        )
    for name, kind in _PAYLOAD_FIELDS.items():
        if not isinstance(payload.get(name), kind):
            raise CheckpointUnreadable(
                f"{path}: field '{name}' is not a {kind.__name__} "
                f"({type(payload.get(name)).__name__})"
            )
    return payload
