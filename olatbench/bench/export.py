"""``olatbench export``: a finished job's Gaussians as a 3DGS-layout PLY (`olatbench.gaussians.splat_ply`).

The Gaussians are read from the job's final checkpoint (the folder is checked as `olatbench.bench.restore` checks
it; no scene or image is read): the core parameters as stored (centres, log-scales, wxyz quaternions, opacity
logits), the colour as the method says (`GaussianMethod.splat_colour`: SSD-GS and GS³ their diffuse albedo as a
degree-0 SH colour, 3DGS its SH coefficients), and every other per-Gaussian attribute as extra properties. A method
trained in a canonical frame (`Views.frame`, stored in the checkpoint) has its centres, scales, rotations and
view-dependent SH moved back into the dataset's world frame and units; the extra attributes are written as stored.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from olatbench.bench.checkpoints import load_checkpoint
from olatbench.bench.restore import RestoreError, check_job
from olatbench.datasets.similarity import Similarity
from olatbench.gaussians.splat_ply import SplatCloud, write_splat_ply

ATTRIBUTE_PREFIX = "attributes."


@dataclass(frozen=True)
class Exported:
    """What `export_ply` wrote: the file, the number of Gaussians, the checkpoint step and the extra properties'
    attribute names."""

    path: Path
    gaussians: int
    step: int
    extras: tuple[str, ...]


def _numpy(tensor: torch.Tensor):
    return tensor.detach().to("cpu", torch.float32).numpy()


def export_ply(job_folder: str | Path, output: str | Path) -> Exported:
    """Write the Gaussians of the finished job in ``job_folder`` to ``output`` (a `RestoreError` naming the file
    when the folder, its checkpoint or its method cannot give them)."""
    from olatbench.methods.baselines.sh import rotate_sh
    from olatbench.methods.gaussian_method import GaussianMethod

    folder = Path(job_folder)
    job, checkpoint, cls = check_job(folder)
    if not issubclass(cls, GaussianMethod):
        raise RestoreError(f"{folder / 'job.json'}: method '{job.method}' is not a Gaussian method on olatbench's "
                           "core; it has no Gaussians to export")
    try:
        payload = load_checkpoint(checkpoint, job.id)
    except RuntimeError as error:
        raise RestoreError(str(error)) from None
    model = payload["method"].get("model") if isinstance(payload.get("method"), dict) else None
    core = ("means", "log_scales", "quats", "opacity_logits")
    if not isinstance(model, dict) or any(name not in model for name in core):
        raise RestoreError(f"{checkpoint}: no Gaussian model (expected method.model with {', '.join(core)})")
    attributes = {name[len(ATTRIBUTE_PREFIX):]: value for name, value in model.items()
                  if name.startswith(ATTRIBUTE_PREFIX)}
    try:
        colour = cls.splat_colour(attributes, job.colourspace)
    except (KeyError, NotImplementedError) as error:
        raise RestoreError(f"{checkpoint}: cannot colour the Gaussians of '{job.method}' ({error})") from None
    extras = {name: _numpy(value) for name, value in attributes.items() if name not in colour.encoded}
    stored_frame = payload["method"].get("frame")  # absent before the canonical frame: the dataset's frame
    to_world = (Similarity.identity() if stored_frame is None else Similarity.from_dict(stored_frame)).inverse()
    sh_rest = colour.sh_rest if to_world.is_identity or colour.sh_rest.shape[-2] == 0 else \
        rotate_sh(colour.sh_rest.detach().cpu(), torch.as_tensor(to_world.rotation))
    cloud = SplatCloud(means=to_world.points(_numpy(model["means"])).astype(np.float32),
                       log_scales=to_world.log_scales(_numpy(model["log_scales"])).astype(np.float32),
                       quats=to_world.quaternions(_numpy(model["quats"])).astype(np.float32),
                       opacity_logits=_numpy(model["opacity_logits"]).reshape(-1),
                       sh_dc=_numpy(colour.sh_dc), sh_rest=_numpy(sh_rest), extras=extras,
                       comments=(f"olatbench export of job {job.id}: {job.method}/{job.variant}/{job.scene}/seed"
                                 f"{job.seed}, step {payload['step']}", colour.description,
                                 "extra properties: raw per-Gaussian attributes " + (", ".join(extras) or "(none)")))
    path = write_splat_ply(output, cloud)
    return Exported(path, len(cloud.means), int(payload["step"]), tuple(extras))


__all__ = ["Exported", "export_ply"]
