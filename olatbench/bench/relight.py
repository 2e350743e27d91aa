"""A trained method's image under a lighting (`olatbench.datasets.lighting`): the sum, in linear
light, of its renders under the point and directional lights that stand for it.

Each light is rendered by the method as a point-light probe at the training irradiance, decoded from
the job's colour space to linear light, weighted by its own irradiance over the training one and
summed, one render at a time; a directional light is a point light at ``distant_factor`` × the
training lights' distance; the background is counted once. docs/relighting.md ("Rendering a trained
model under a lighting") explains each choice and what was measured.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from olatbench.bench.jobs import Job
from olatbench.datasets import colour
from olatbench.datasets.lighting import SampledLights
from olatbench.datasets.records import Camera, PointLight
from olatbench.datasets.similarity import axes_centre, canonical_frame
from olatbench.methods.base import Method, Views
from olatbench.progress import progress_bar

# directional lights probed at the training lights' distance (module docstring)
DISTANT_FACTOR = 1.0


class RelightError(ValueError):
    """A lighting that a job cannot be rendered under; the message says why and what would do."""


@dataclass(frozen=True)
class LightingReference:
    """What the training lights were, seen from the scene: ``centre`` (3,) the point nearest every
    training camera's axis, ``up`` (3,) the rig's vertical (as the canonical frame's +z),
    ``distance`` the training lights' median distance from the centre, ``irradiance`` (3,) their
    median RGB irradiance ``I / d²`` at the centre."""

    centre: np.ndarray
    up: np.ndarray
    distance: float
    irradiance: np.ndarray

    @classmethod
    def of(cls, cameras: Sequence[Camera], lights: Sequence[PointLight]) -> LightingReference:
        """The reference of a training split's cameras and lights (world frame)."""
        centre = axes_centre(cameras)
        up = canonical_frame(cameras).rotation[2]
        offsets = (
            np.stack([np.asarray(light.position, dtype=np.float64) for light in lights]) - centre
        )
        d2 = np.sum(offsets**2, axis=1)
        if not np.all(d2 > 0.0):
            raise RelightError(
                "a training light sits at the scene centre: no training irradiance is defined"
            )
        irradiance = np.median(
            np.stack([light.intensity for light in lights]) / d2[:, None], axis=0
        )
        if not np.all(irradiance > 0.0):
            raise RelightError(
                "the training lights give no light in some channel (irradiance "
                f"{irradiance.tolist()}) at the scene centre: the method cannot show light there"
            )
        return cls(centre, up, float(np.sqrt(np.median(d2))), irradiance)


@dataclass(frozen=True)
class Probe:
    """One render of a relight: the point ``light`` the method renders, and the RGB ``weight`` (3,)
    of its image in linear light."""

    light: PointLight
    weight: np.ndarray


def probes(
    lights: SampledLights, reference: LightingReference, distant_factor: float = DISTANT_FACTOR
) -> list[Probe]:
    """The probes of the point and directional lights (module docstring)."""
    out = []
    for light in lights.points:
        position = np.asarray(light.position, dtype=np.float64)
        d2 = float(np.sum((position - reference.centre) ** 2))
        if not d2 > (1e-6 * reference.distance) ** 2:
            raise RelightError(
                f"a point light at the scene centre {position.tolist()}: its irradiance there is "
                "undefined; move it"
            )
        out.append(
            Probe(
                PointLight(position, reference.irradiance * d2, True),
                np.asarray(light.intensity, dtype=np.float64) / d2 / reference.irradiance,
            )
        )
    distance = distant_factor * reference.distance
    for light in lights.directions:
        position = reference.centre + distance * np.asarray(light.direction, dtype=np.float64)
        out.append(
            Probe(
                PointLight(position, reference.irradiance * distance**2, True),
                np.asarray(light.irradiance, dtype=np.float64) / reference.irradiance,
            )
        )
    return out


@dataclass
class Relighter:
    """Renders a trained ``method`` under lightings: ``colourspace`` and ``background`` (3,) (in it)
    the job's, ``reference`` its training lights' (`LightingReference`), directional lights probed
    at ``distant_factor`` × the training lights' distance."""

    method: Method
    colourspace: colour.ColourSpace
    background: np.ndarray
    reference: LightingReference
    distant_factor: float = DISTANT_FACTOR

    @classmethod
    def for_views(cls, method: Method, train: Views) -> Relighter:
        """A relighter for ``method`` trained on ``train`` (world cameras and lights, as
        `frame_views` gives)."""
        return cls(
            method,
            train.colourspace,
            np.asarray(train.background, dtype=np.float32).reshape(3),
            LightingReference.of(train.cameras, train.lights),
        )

    @property
    def relightable(self) -> bool:
        """Whether the method's render depends on the light (its ``relight`` capability)."""
        return "relight" in self.method.capabilities

    def probes(self, lights: SampledLights) -> list[Probe]:
        return probes(lights, self.reference, self.distant_factor)

    def linear(self, camera: Camera, lights: SampledLights, progress: bool = False) -> np.ndarray:
        """The linear RGB image (H, W, 3) float32 of ``camera`` under ``lights``
        (module docstring)."""
        import torch

        todo = self.rendered_probes(lights)
        total, empty = None, None
        with torch.no_grad():
            for probe in progress_bar(
                todo,
                desc="lights",
                unit="light",
                disable=not progress or len(todo) < 2,
                leave=False,
            ):
                lit, empty = self.contribution(camera, probe)
                total = lit if total is None else total + lit
        return self.composite(total, empty)

    def rendered_probes(self, lights: SampledLights) -> list[Probe]:
        """The probes `linear` renders, in its order: `probes`, or for a method that ignores the
        light one probe carrying their summed weight."""
        if len(lights) == 0:
            raise RelightError("the lighting has no lights")
        todo = self.probes(lights)
        if not self.relightable:  # one render: the light changes nothing but the summed weight
            todo = [Probe(todo[0].light, np.sum([probe.weight for probe in todo], axis=0))]
        return todo

    def contribution(self, camera: Camera, probe: Probe) -> tuple[np.ndarray, np.ndarray]:
        """(the probe's weighted light without the background, linear (H, W, 3) float32; the
        uncovered share 1 - alpha (H, W, 1)): `linear` is `composite` of the sum of these over
        `rendered_probes`."""
        lit, empty = self._linear_render(camera, probe.light)
        return lit * probe.weight.astype(np.float32), empty

    def composite(self, total: np.ndarray, empty: np.ndarray) -> np.ndarray:
        """A sum of `contribution` images (H, W, 3) with the job's background, in linear light, put
        back once where the scene is uncovered (``empty`` (H, W, 1)): (H, W, 3) float32."""
        background = colour.convert_colourspace(
            self.background.reshape(1, 1, 3), self.colourspace, "linear"
        )
        return (total + empty * background).astype(np.float32)

    def _linear_render(self, camera: Camera, light: PointLight) -> tuple[np.ndarray, np.ndarray]:
        """(the render's light without the background, linear (H, W, 3); the uncovered share 1 -
        alpha (H, W, 1))."""
        output = self.method.render(camera, light)
        rgb = output["rgb"].detach().to("cpu").float().numpy()
        if "alpha" in output:
            empty = 1.0 - np.clip(
                output["alpha"].detach().to("cpu").float().numpy().reshape(*rgb.shape[:2], 1),
                0.0,
                1.0,
            )
        elif np.any(self.background != 0.0):
            raise RelightError(
                f"method '{getattr(self.method, 'name', type(self.method).__name__)}' renders no "
                "'alpha': it can be relit on a black background only, and this job's is "
                f"{self.background.tolist()}"
            )
        else:
            empty = np.zeros((*rgb.shape[:2], 1), dtype=np.float32)
        lit = np.clip(rgb - empty * self.background, 0.0, None)
        return colour.convert_colourspace(lit, self.colourspace, "linear"), empty

    def display(self, camera: Camera, lights: SampledLights, progress: bool = False) -> np.ndarray:
        """The image as it is shown: `shown` of `linear`."""
        return shown(self.linear(camera, lights, progress))


def shown(linear: np.ndarray) -> np.ndarray:
    """A linear image (H, W, 3) as it is shown: sRGB-encoded, clipped to [0, 1], float32."""
    return np.clip(colour.convert_colourspace(linear, "linear", "srgb"), 0.0, 1.0)


def restore_relighter(
    job_folder: str | Path, device: str = "cpu", progress: bool = False
) -> tuple[Relighter, Job]:
    """The `Relighter` of a finished job's trained method (`olatbench.bench.restore.restore`: a
    `RestoreError` naming the file when it cannot be rebuilt) and the job, referenced to its
    training split's lights."""
    from olatbench.bench.restore import RestoreError, restore
    from olatbench.bench.views import frame_views
    from olatbench.datasets import load_scene
    from olatbench.datasets.errors import DatasetError

    method, job = restore(job_folder, device, progress=progress)
    try:
        frames = load_scene(job.scene_path, format=job.scene_format).split(job.train_split)
    except (DatasetError, OSError, KeyError, ValueError) as error:
        raise RestoreError(
            f"{Path(job_folder) / 'job.json'}: cannot read the scene {job.scene_path} ({error})"
        ) from None
    return Relighter.for_views(method, frame_views(frames, job)), job


__all__ = [
    "DISTANT_FACTOR",
    "LightingReference",
    "Probe",
    "RelightError",
    "Relighter",
    "probes",
    "restore_relighter",
    "shown",
]
