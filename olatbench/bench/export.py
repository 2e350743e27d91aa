"""``olatbench export``: a finished job's Gaussians as a 3DGS-layout PLY
(`olatbench.gaussians.splat_ply`).

The Gaussians are read from the job's final checkpoint (the folder is checked as
`olatbench.bench.restore` checks it; no scene or image is read): the core parameters as stored
(centres, log-scales, wxyz quaternions, opacity logits), the colour as the method says
(`GaussianMethod.splat_colour`: SSD-GS and GS³ their diffuse albedo as a degree-0 SH colour, 3DGS
its SH coefficients), and every other per-Gaussian attribute as extra properties. A method trained
in a canonical frame (`Views.frame`, stored in the checkpoint) has its centres, scales, rotations
and view-dependent SH moved back into the dataset's world frame and units; the extra attributes are
written as stored.

With ``under_light`` the colour is instead **baked** under one light (`baked_colour`): the trained
method is restored, each Gaussian's colour under that light (`GaussianMethod.colours_under`) is
taken from a set of cameras (the training cameras, or one named frame's), converted to sRGB, and
fitted per Gaussian by least squares with SH of degree ``sh_degree``
(`olatbench.methods.baselines.sh.SHFit`; degree 0: the mean over the cameras, the view-independent
part) along directions in the canonical frame, moved to the world frame with the rest. The file is a
picture of the model under that light, not a relightable model. Under a lighting (`Bake.lighting`:
several lights, area lights, an environment map) each Gaussian's colour is the sum in linear light
of its colours under the lighting's point and directional lights, as `olatbench.bench.relight` sums
renders.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from olatbench.bench.checkpoints import load_checkpoint
from olatbench.bench.restore import RestoreError, check_job
from olatbench.datasets.lighting import Lighting
from olatbench.datasets.similarity import Similarity
from olatbench.gaussians.splat_ply import SplatCloud, write_splat_ply
from olatbench.methods.gaussian_method import SplatColour
from olatbench.names import did_you_mean
from olatbench.progress import progress_bar

ATTRIBUTE_PREFIX = "attributes."


@dataclass(frozen=True)
class Exported:
    """What `export_ply` wrote: the file, the number of Gaussians, the checkpoint step and the extra
    properties' attribute names."""

    path: Path
    gaussians: int
    step: int
    extras: tuple[str, ...]


def _numpy(tensor: torch.Tensor):
    return tensor.detach().to("cpu", torch.float32).numpy()


class BakeRequestError(RestoreError):
    """A bake the job cannot give (a light or frame it does not have, an SH degree out of range, a
    method without colours under a light); the message says what it has."""


@dataclass(frozen=True)
class Bake:
    """What `export_ply` bakes into the colours: the light (`olatbench.datasets.lights.parse_light`:
    a training light index or ``x,y,z``; its name when ``lighting`` is given), the SH degree of the
    fit (0 … 3), and the cameras seen from: ``view`` a frame id of the test split, else of the
    training split (that camera alone), else up to ``max_views`` training cameras spread evenly over
    the split's order. ``lighting`` bakes under a lighting instead of one light, its area lights and
    maps sampled with ``samples`` lights each (None: the lighting's)."""

    light: str
    sh_degree: int = 0
    view: str | None = None
    max_views: int = 64
    lighting: Lighting | None = None
    samples: int | None = None


def export_ply(
    job_folder: str | Path,
    output: str | Path,
    bake: Bake | None = None,
    device: str = "cpu",
    progress: bool = False,
) -> Exported:
    """Write the Gaussians of the finished job in ``job_folder`` to ``output``, coloured as the
    method says or, with ``bake``, under a light (`baked_colour`); a `RestoreError` naming the file
    when the folder, its checkpoint or its method cannot give them."""
    from olatbench.methods.baselines.sh import rotate_sh
    from olatbench.methods.gaussian_method import GaussianMethod

    folder = Path(job_folder)
    job, checkpoint, cls = check_job(folder)
    if not issubclass(cls, GaussianMethod):
        raise RestoreError(
            f"{folder / 'job.json'}: method '{job.method}' is not a Gaussian method on olatbench's "
            "core; it has no Gaussians to export"
        )
    try:
        payload = load_checkpoint(checkpoint, job.id)
    except RuntimeError as error:
        raise RestoreError(str(error)) from None
    model = payload["method"].get("model") if isinstance(payload.get("method"), dict) else None
    core = ("means", "log_scales", "quats", "opacity_logits")
    if not isinstance(model, dict) or any(name not in model for name in core):
        raise RestoreError(
            f"{checkpoint}: no Gaussian model (expected method.model with {', '.join(core)})"
        )
    attributes = {
        name[len(ATTRIBUTE_PREFIX) :]: value
        for name, value in model.items()
        if name.startswith(ATTRIBUTE_PREFIX)
    }
    try:
        colour = (
            cls.splat_colour(attributes, job.colourspace)
            if bake is None
            else baked_colour(folder, bake, device, progress)
        )
    except (KeyError, NotImplementedError) as error:
        raise RestoreError(
            f"{checkpoint}: cannot colour the Gaussians of '{job.method}' ({error})"
        ) from None
    if len(colour.sh_dc) != len(model["means"]):
        raise RestoreError(
            f"{checkpoint}: the restored model has {len(colour.sh_dc)} Gaussians, the checkpoint "
            f"{len(model['means'])}"
        )
    extras = {
        name: _numpy(value) for name, value in attributes.items() if name not in colour.encoded
    }
    # absent before the canonical frame: the dataset's frame
    stored_frame = payload["method"].get("frame")
    to_world = (
        Similarity.identity() if stored_frame is None else Similarity.from_dict(stored_frame)
    ).inverse()
    sh_rest = (
        colour.sh_rest
        if to_world.is_identity or colour.sh_rest.shape[-2] == 0
        else rotate_sh(colour.sh_rest.detach().cpu(), torch.as_tensor(to_world.rotation))
    )
    cloud = SplatCloud(
        means=to_world.points(_numpy(model["means"])).astype(np.float32),
        log_scales=to_world.log_scales(_numpy(model["log_scales"])).astype(np.float32),
        quats=to_world.quaternions(_numpy(model["quats"])).astype(np.float32),
        opacity_logits=_numpy(model["opacity_logits"]).reshape(-1),
        sh_dc=_numpy(colour.sh_dc),
        sh_rest=_numpy(sh_rest),
        extras=extras,
        comments=(
            f"olatbench export of job {job.id}: {job.method}/{job.variant}/{job.scene}/seed"
            f"{job.seed}, step {payload['step']}",
            colour.description,
            "extra properties: raw per-Gaussian attributes " + (", ".join(extras) or "(none)"),
        ),
    )
    path = write_splat_ply(output, cloud)
    return Exported(path, len(cloud.means), int(payload["step"]), tuple(extras))


def bake_cameras(method, job, bake: Bake) -> list:
    """The cameras a bake sees the Gaussians from (see `Bake`), at the job's resolution, in the
    dataset's world frame."""
    from olatbench.bench.views import view_camera
    from olatbench.datasets import load_scene

    train = method.train_views.views  # in the method's canonical frame
    if bake.view is None:
        count = min(bake.max_views, len(train))
        to_world = method.frame.inverse()
        return [
            to_world.camera(train.cameras[i])
            for i in np.linspace(0, len(train) - 1, count).round().astype(int)
        ]
    scene = load_scene(job.scene_path, format=job.scene_format)
    # test first, as render --start-frame
    frames = scene.split(job.test_split) + scene.split(job.train_split)
    for frame in frames:
        if frame.frame_id == bake.view:
            return [view_camera(frame, job)]
    raise BakeRequestError(
        f"{job.scene_path}: no frame {bake.view!r} in the test or train split"
        f"{did_you_mean(bake.view, [frame.frame_id for frame in frames])}"
    )


def _colours_under(method, camera, probes: list, colourspace: str, single: bool) -> np.ndarray:
    """The sRGB colour (N, 3) of every Gaussian seen from the world ``camera`` under the probes'
    lights (`olatbench.bench.relight.Probe`): the sum of their weighted colours in linear light, or
    with ``single`` the one probe's colour converted as it is."""
    from olatbench.datasets.colour import convert_colourspace

    total = None
    for probe in probes:
        seen_from, lit_by = method.canonical_view(camera, probe.light)
        colours = method.colours_under(seen_from, lit_by).detach().double().cpu().numpy()
        if single:
            return convert_colourspace(colours, colourspace, "srgb")
        linear = probe.weight * convert_colourspace(colours, colourspace, "linear")
        total = linear if total is None else total + linear
    return convert_colourspace(total, "linear", "srgb")


def baked_colour(
    job_folder: str | Path, bake: Bake, device: str = "cpu", progress: bool = False
) -> SplatColour:
    """The job's Gaussians' colours under ``bake.light`` as sRGB SH coefficients (degree-3 layout,
    the coefficients above ``bake.sh_degree`` zero), fitted over the bake's cameras
    (module docstring)."""
    from olatbench.bench.relight import Probe
    from olatbench.bench.restore import restore
    from olatbench.datasets.lights import parse_light
    from olatbench.methods.baselines.sh import MAX_DEGREE, SHFit, num_coefficients
    from olatbench.methods.gaussian_method import VIEWER_SH_REST, GaussianMethod

    if not 0 <= bake.sh_degree <= MAX_DEGREE:
        raise BakeRequestError(f"--sh-degree must be 0 … {MAX_DEGREE}, not {bake.sh_degree}")
    relighter = None
    if bake.lighting is not None:
        from olatbench.bench.relight import RelightError, restore_relighter
        from olatbench.datasets.errors import DatasetError

        try:
            relighter, job = restore_relighter(job_folder, device, progress)
            lit_probes = relighter.probes(
                bake.lighting.sample(relighter.reference.up, bake.samples)
            )
        except (RelightError, DatasetError) as error:
            raise BakeRequestError(str(error)) from None
        method = relighter.method
    else:
        method, job = restore(job_folder, device, progress=progress)
    if (
        not isinstance(method, GaussianMethod)
        or type(method).colours_under is GaussianMethod.colours_under
    ):
        raise BakeRequestError(
            f"{Path(job_folder) / 'job.json'}: method '{job.method}' has no colour under a light "
            "(it is not relightable, or does not say: GaussianMethod.colours_under); export it "
            "without --under-light"
        )
    to_world = method.frame.inverse()
    if relighter is None:
        # the light as the user names it: a training light or a position, in the dataset's world
        # frame
        try:
            light = parse_light(
                bake.light, [to_world.light(lt) for lt in method.train_views.views.lights]
            )
        except ValueError as error:
            raise BakeRequestError(str(error)) from None
        lit_probes = [Probe(light, np.ones(3))]  # as it is: no detour through linear light
    cameras = bake_cameras(method, job, bake)
    # canonical, as the fit's directions: export_ply moves the SH back
    means = method.model.means.detach().double()
    fit = SHFit(len(means), bake.sh_degree, device=means.device)
    for camera in progress_bar(
        cameras, desc=f"bake {job.method}/{job.scene}", unit="view", disable=not progress
    ):
        shown = torch.from_numpy(
            _colours_under(method, camera, lit_probes, job.colourspace, relighter is None)
        )
        seen_from = method.frame.camera(camera).position
        fit.add(
            torch.nn.functional.normalize(means - torch.as_tensor(seen_from).to(means), dim=-1),
            shown,
        )
    coefficients = fit.solve().cpu()
    rest = torch.zeros(len(means), VIEWER_SH_REST, 3)
    rest[:, : num_coefficients(bake.sh_degree) - 1] = coefficients[:, 1:]
    seen = (
        f"camera of frame {bake.view}"
        if bake.view is not None
        else f"{len(cameras)} training cameras"
    )
    under = (
        f"lighting {bake.light} ({len(lit_probes)} lights, summed in linear light)"
        if relighter is not None
        else f"light {bake.light}"
    )
    return SplatColour(
        coefficients[:, 0],
        rest,
        (),
        f"colour: a bake, not relightable: the colour under {under} "
        f"({job.colourspace} -> sRGB, not clipped) fitted with degree-{bake.sh_degree} SH over the "
        f"{seen}",
    )


__all__ = ["Bake", "BakeRequestError", "Exported", "bake_cameras", "baked_colour", "export_ply"]
