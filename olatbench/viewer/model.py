"""What the viewer shows of one trained job: the restored method, its scene's frames, the light's
frame, renders.

`ViewerModel.open` restores the method from the job's newest checkpoint through
`olatbench.bench.restore` (no training image is read) and reads the scene's frame records. For a job
still training, `reload_if_newer` restores a newer checkpoint when the runner has written one and
swaps it in between two renders. Renders are converted for display as the sweeps do
(`olatbench.reports.video.display_image`: sRGB, 8-bit). Ground truth is read only for a frame the
user snaps to, and compared in the job's evaluation colour space as the runner scores
(both clipped to [0, 1]).

Under an environment map (`olatbench.viewer.environment`) the model is relit through
`olatbench.bench.relight` as ``olatbench render --envmap`` relights it (the same samples for the
same settings), progressively (`olatbench.bench.progressive`): the map is stood on the training
rig's vertical and sampled once per setting (a few are cached).
"""

from __future__ import annotations

import dataclasses
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from olatbench.bench.progressive import ProgressiveRelight
from olatbench.bench.relight import Relighter, shown
from olatbench.bench.restore import RestoreError, newest_checkpoint, restore
from olatbench.bench.results import ResultsError, read_results
from olatbench.bench.store import RESULTS_FILE, list_checkpoints
from olatbench.bench.views import frame_views, view_camera
from olatbench.datasets import colour, load_scene
from olatbench.datasets.lighting import SampledLights
from olatbench.datasets.records import Camera, Frame, PointLight
from olatbench.metrics.psnr import psnr
from olatbench.reports.sweeps import orbit_frame
from olatbench.reports.video import display_image
from olatbench.viewer.environment import EnvironmentSettings
from olatbench.viewer.geometry import LightFrame

CACHED_LIGHTINGS = 4  # sampled environment settings kept per model


@dataclass(frozen=True)
class ViewerFrame:
    """A dataset frame the viewer can snap to: its camera at the job's resolution and its light."""

    split: str
    frame: Frame
    camera: Camera

    @property
    def frame_id(self) -> str:
        return self.frame.frame_id

    @property
    def light(self) -> PointLight:
        return self.frame.light

    @property
    def label(self) -> str:
        return f"{self.split}/{self.frame_id}"


@dataclass(frozen=True)
class Comparison:
    """A render of a dataset frame beside its ground truth: both (H, W, 3) uint8 sRGB; ``psnr`` (dB)
    of the render against the ground truth in the job's colour space; ``recorded_psnr`` the
    runner's, from results.json (or None)."""

    frame: ViewerFrame
    render: np.ndarray
    ground_truth: np.ndarray
    psnr: float
    recorded_psnr: float | None


class ViewerModel:
    """One trained job ready to render, restored from its checkpoint at ``step``. `render` and the
    swap of a reloaded checkpoint are serialised by a lock (torch and the native kernels run on the
    calling thread; the viewer's scheduler calls `render` from one thread, the checkpoint follower
    `reload_if_newer` from another)."""

    def __init__(
        self,
        method: Any,
        job: Any,
        train: list[Frame],
        test: list[Frame],
        folder: Path,
        step: int | None = None,
    ) -> None:
        self.method = method
        self.job = job
        self.folder = folder
        self.step = job.iterations if step is None else step
        self.frames = [
            ViewerFrame(split, frame, view_camera(frame, job))
            for split, frames in ((job.test_split, test), (job.train_split, train))
            for frame in frames
        ]
        self.train = [f for f in self.frames if f.split == job.train_split]
        self.test = [f for f in self.frames if f.split == job.test_split]
        first = (self.test or self.train)[0]
        self.home = first
        centre, up = orbit_frame([f.camera for f in self.train])
        self.light_frame = LightFrame.of(centre, up, self.train[0].camera.position)
        self.full_size = (first.camera.width, first.camera.height)
        self._lock = threading.Lock()
        self._train_frames = train
        self._relighter: Relighter | None = None  # built on the first environment-map view
        self._lightings: OrderedDict[EnvironmentSettings, SampledLights] = OrderedDict()
        self.components: tuple[str, ...] = tuple(
            self.render_outputs(first.camera.resized(8, 8), first.light)
        )
        self._recorded = self._recorded_psnr()

    @classmethod
    def open(cls, folder: str | Path, device: str = "cpu") -> ViewerModel:
        """Restore the job in ``folder`` from its newest checkpoint (a
        `olatbench.bench.restore.RestoreError` if it cannot be)."""
        method, job, step = _restore_newest(Path(folder), device)
        scene = load_scene(job.scene_path, format=job.scene_format)
        return cls(
            method,
            job,
            scene.split(job.train_split),
            scene.split(job.test_split),
            Path(folder),
            step,
        )

    @property
    def finished(self) -> bool:
        """Whether the model is the job's final one (no newer checkpoint can come)."""
        return self.step >= self.job.iterations

    @property
    def label(self) -> str:
        job = self.job
        progress = "" if self.finished else f" (step {self.step}/{job.iterations}, training)"
        return f"{job.method}/{job.variant}/{job.scene}/seed{job.seed}{progress}"

    def reload_if_newer(self) -> bool:
        """Restore the job's newest checkpoint if it is newer than the shown one and swap it in (the
        render in flight finishes on the old one); whether it did. A `RestoreError` if the newer
        checkpoint cannot be restored."""
        checkpoints = list_checkpoints(self.folder)
        if not checkpoints or checkpoints[-1][0] <= self.step:
            return False
        method, _, step = _restore_newest(self.folder, str(self.job.device))
        with self._lock:
            self.method, self.step = method, step
        return True

    def frame(self, label: str) -> ViewerFrame:
        """The frame named ``<split>/<frame id>`` (a `KeyError` otherwise)."""
        for frame in self.frames:
            if frame.label == label:
                return frame
        raise KeyError(f"{self.label}: no frame {label!r}")

    def render_outputs(self, camera: Camera, light: PointLight) -> dict[str, Any]:
        """``method.render(camera, light)`` (tensors), serialised."""
        import torch

        with self._lock, torch.no_grad():
            return self.method.render(camera, light)

    def render(self, camera: Camera, light: PointLight, component: str = "rgb") -> np.ndarray:
        """One output for display: (H, W, 3) uint8 sRGB."""
        return self.render_with_step(camera, light, component)[0]

    def render_with_step(
        self, camera: Camera, light: PointLight, component: str = "rgb"
    ) -> tuple[np.ndarray, int]:
        """`render` and the checkpoint step of the model that drew it."""
        import torch

        with self._lock, torch.no_grad():
            outputs, step = self.method.render(camera, light), self.step
        if component not in outputs:
            raise KeyError(
                f"method '{self.job.method}' renders no {component!r}; it renders "
                f"{', '.join(outputs)}"
            )
        return colour.quantize_8bit(display_image(outputs[component], self.job.colourspace)), step

    @property
    def relightable(self) -> bool:
        """Whether the method's render depends on the light (else a lighting only scales its one
        render)."""
        return "relight" in self.method.capabilities

    def _relighter_of_current(self) -> tuple[Relighter, int]:
        """(a relighter of the current model, its step); call with the lock held. A `RelightError`
        when the training lights give no reference irradiance."""
        if self._relighter is None:
            self._relighter = Relighter.for_views(
                self.method, frame_views(self._train_frames, self.job)
            )
        return dataclasses.replace(self._relighter, method=self.method), self.step

    def environment_lights(self, settings: EnvironmentSettings) -> SampledLights:
        """The directional lights of ``settings`` (stood on the training rig's vertical, as
        ``olatbench render`` stands a map), cached; a `DatasetError` for a map that cannot be
        read."""
        with self._lock:
            lights = self._lightings.get(settings)
            if lights is not None:
                self._lightings.move_to_end(settings)
                return lights
            up = self._relighter_of_current()[0].reference.up
        lights = settings.lighting().sample(up)
        with self._lock:
            self._lightings[settings] = lights
            while len(self._lightings) > CACHED_LIGHTINGS:
                self._lightings.popitem(last=False)
        return lights

    def progressive(
        self, camera: Camera, settings: EnvironmentSettings
    ) -> tuple[ProgressiveRelight, int]:
        """A progressive relight of ``camera`` under ``settings`` by the current model, and that
        model's step (the relight keeps that model, even when a newer checkpoint is swapped in
        meanwhile)."""
        lights = self.environment_lights(settings)
        with self._lock:
            relighter, step = self._relighter_of_current()
        return ProgressiveRelight(relighter, camera, lights), step

    def refine(
        self, relight: ProgressiveRelight, count: int, stop: Callable[[], bool] | None = None
    ) -> np.ndarray | None:
        """Render ``count`` more probes of ``relight`` (fewer if ``stop()`` turns true first),
        serialised with the other renders; its image for display, (H, W, 3) uint8 sRGB (None when
        nothing has been rendered yet)."""
        with self._lock:
            relight.advance(count, stop)
        return colour.quantize_8bit(shown(relight.estimate())) if relight.done else None

    def compare(self, frame: ViewerFrame) -> Comparison:
        """Render ``frame`` with its own camera and light and put it beside the ground truth."""
        outputs = self.render_outputs(frame.camera, frame.light)
        space = self.job.colourspace
        prediction = np.clip(outputs["rgb"].detach().cpu().float().numpy(), 0.0, 1.0)
        resolution = tuple(self.job.resolution) if self.job.resolution else None
        truth = np.clip(
            frame.frame.load(colourspace=space, background="official", resolution=resolution).rgb,
            0.0,
            1.0,
        )
        return Comparison(
            frame,
            colour.quantize_8bit(display_image(outputs["rgb"], space)),
            colour.quantize_8bit(
                np.clip(colour.convert_colourspace(truth, space, "srgb"), 0.0, 1.0)
            ),
            float(psnr(prediction, truth)),
            self._recorded.get(frame.label),
        )

    def _recorded_psnr(self) -> dict[str, float]:
        """``<split>/<frame id>`` -> the PSNR the runner recorded (results.json), when it is
        there."""
        # the one reader of results.json: a damaged or hand-edited file is refused there, whatever
        # its shape
        try:
            results = read_results(self.folder / RESULTS_FILE)
        # none, or unreadable (`olatbench status` names it): the viewer shows no recorded PSNR
        except ResultsError:
            return {}
        return {
            f"{split}/{frame_id}": float(scores["psnr"])
            for split, block in results["metrics"].items()
            for frame_id, scores in block.get("per_image", {}).items()
            if scores.get("psnr") is not None
        }


def _restore_newest(folder: Path, device: str, attempts: int = 3) -> tuple[Any, Any, int]:
    """(method, job, step) of the newest checkpoint; a checkpoint the runner prunes between the
    listing and the load (it keeps the newest few) is retried with the then newest."""
    for attempt in range(attempts):
        step, path = newest_checkpoint(folder)
        try:
            method, job = restore(folder, device, checkpoint=path)
        except RestoreError:
            if path.exists() or attempt == attempts - 1:
                raise
            continue
        return method, job, step
    raise AssertionError("unreachable")
