"""The method interface: what the runner needs from any relightable reconstruction method.

The runner owns the training loop (progress, checkpoints, evaluation, timing), so a
method only has to answer these calls. Images handed to a method are float32 in
[0, 1], composited on the suite's background, in the suite's training colour space;
renders must be returned in the same space.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from olatbench.datasets.similarity import Similarity
from olatbench.methods.resolve import SET_SOURCE, ResolvedConfig, resolve
from olatbench.methods.spec import DEFAULT_EVALUATION, MethodSpec

if TYPE_CHECKING:
    import torch

    from olatbench.datasets.records import Camera, PointLight


@dataclass
class Views:
    """Training (or evaluation) views: one camera, light and image per entry.

    ``images`` is (N, H, W, 3) float32 in [0, 1] in ``colourspace``, composited on ``background``
    (3,); it is None when a trained method is restored for rendering and declared it needs no images
    (`Method.restore_needs_images`). ``points`` (P, 3) float64 are world points (the scene's frame)
    for a method with the ``init_points`` capability to start its Gaussians at (the scene's
    ``points3d.ply`` or ``run --init-points``), or None.

    Cameras and lights are in the dataset's world frame; ``frame`` is the world -> canonical
    similarity the runner chose for the job (`olatbench.datasets.similarity`: fitted to the training
    cameras, or the identity for the built-in suites), which a method works in so that nothing it
    does depends on the world's origin, axes or unit of length (the Gaussian methods do:
    `GaussianMethod`).
    """

    cameras: list[Camera]
    lights: list[PointLight]
    images: np.ndarray | None
    frame_ids: list[str]
    colourspace: str = "srgb"
    background: np.ndarray = field(default_factory=lambda: np.zeros(3, dtype=np.float32))
    scene_name: str = ""
    points: np.ndarray | None = None
    frame: Similarity = field(default_factory=Similarity.identity)

    def __len__(self) -> int:
        return len(self.cameras)

    def in_frame(self) -> Views:
        """These views with cameras, lights and initial points moved into ``frame``
        (`Similarity.camera`, `Similarity.light`, `Similarity.points`); the result's ``frame`` is
        the identity (it is its own world)."""
        if self.frame.is_identity:
            return self
        points = None if self.points is None else self.frame.points(self.points)
        return replace(
            self,
            cameras=[self.frame.camera(c) for c in self.cameras],
            lights=[self.frame.light(lt) for lt in self.lights],
            points=points,
            frame=Similarity.identity(),
        )


class Method(ABC):
    """A trainable method. Subclasses set ``name``, ``config_class`` and ``presets``.

    ``presets`` maps a preset name (e.g. ``"nrhints"``, ``"mini"``, ``"ablation-A"``) to a dict of
    config overrides; ``resolve_config`` applies them over the dataclass defaults. What the runner
    and `olatbench methods` read without importing the class lives in the method's `MethodSpec`.
    """

    name: ClassVar[str]
    config_class: ClassVar[type]
    presets: ClassVar[dict[str, dict[str, Any]]] = {}
    description: ClassVar[str] = ""
    #: Named grids of presets (``run --ablation NAME``: a sequence of variants, or an `AblationGrid`
    #: naming its reference variant), for methods registered as a class (plugins, tests); built-in
    #: methods declare theirs in their `MethodSpec`.
    ablations: ClassVar[dict[str, Sequence[str]]] = {}
    #: Whether `setup` needs the training images when the method is restored from its final
    #: checkpoint to render (`olatbench.bench.restore`). False: `setup` then gets
    #: ``Views.images = None`` (cameras, lights and frame ids are always given, in training order,
    #: so per-view state stays addressable by frame id), and a sweep or the viewer reads no training
    #: image. True (the safe default for plugins): the images are loaded.
    restore_needs_images: ClassVar[bool] = True
    #: Training steps the method always takes, replacing the suite's (None: the suite's; 0:
    #: learning-free, all the work is in `setup`), for methods registered as a class; built-in
    #: methods declare it in their `MethodSpec`.
    training_iterations: ClassVar[int | None] = None
    #: What the method can do (`olatbench.methods.spec.CAPABILITIES`), for methods registered as a
    #: class; built-in methods declare them in their `MethodSpec`.
    capabilities: ClassVar[frozenset[str]] = frozenset()
    #: The method's evaluation protocol
    #: (``"module:Class"``, `olatbench.methods.evaluation_protocol`): how its test views are posed
    #: before they are scored; built-in methods name theirs in their `MethodSpec`.
    evaluation: ClassVar[str] = DEFAULT_EVALUATION

    def __init_subclass__(cls, spec: MethodSpec | None = None, **kwargs: Any) -> None:
        """``class SSDGS(GaussianMethod, spec=SPEC)`` takes ``name``, ``presets``, ``description``,
        ``ablations``, ``capabilities`` and ``evaluation`` from the method's spec, so they are
        written once (and a class registered by name keeps them)."""
        super().__init_subclass__(**kwargs)
        if spec is not None:
            cls.name, cls.presets, cls.description = spec.name, dict(spec.presets), spec.description
            cls.ablations = dict(spec.ablations)
            cls.training_iterations = spec.iterations
            cls.capabilities = frozenset(spec.capabilities)
            cls.evaluation = spec.evaluation

    def __init__(self, config: Any) -> None:
        self.config = config

    @classmethod
    def resolve_config(cls, preset: str | None = None, **overrides: Any) -> Any:
        """The config dataclass with the presets named in ``preset`` (``"mini+ablation-C"``: left to
        right), then explicit overrides, applied (`olatbench.methods.resolve`, the one resolution
        path)."""
        return cls.resolve_sources(preset, overrides).config

    @classmethod
    def resolve_sources(
        cls,
        preset: str | None = None,
        overrides: Mapping[str, Any] | None = None,
        overrides_source: str = SET_SOURCE,
    ) -> ResolvedConfig:
        """`resolve_config` with the source of each field's value (``overrides`` reported as
        ``overrides_source``: ``"job.json"`` when a job's config is rebuilt)."""
        return resolve(cls.name, cls.config_class, cls.presets, preset, overrides, overrides_source)

    @abstractmethod
    def setup(self, train: Views, device: str | torch.device, seed: int) -> None:
        """Initialise parameters and optimisers for the training views."""

    @abstractmethod
    def train_step(self, step: int) -> dict[str, Any]:
        """One optimisation step (``step`` counts from 0); returns scalars such as ``loss``:
        anything ``float()`` reads (numbers, 0-d tensors, `olatbench.methods.training.LazyScalar`).
        The runner reads them only at its logging interval and at checkpoints, so a step on a GPU
        need not wait for the device to report them."""

    @abstractmethod
    def render(self, camera: Camera, light: PointLight) -> dict[str, torch.Tensor]:
        """Render one view: ``rgb`` (H, W, 3) plus named components (``diffuse``, ``shadow``,
        ...)."""

    @abstractmethod
    def state_dict(self) -> dict[str, Any]:
        """Everything needed to resume training: tensors and plain Python values only."""

    @abstractmethod
    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore what `state_dict` returned (loaded with ``torch.load(weights_only=True)``)."""

    @property
    def num_iterations(self) -> int:
        """Total training iterations of the resolved config."""
        return int(self.config.iterations)

    @property
    def num_gaussians(self) -> int | None:
        """Current primitive count, when the method has one."""
        return None

    def backends(self) -> dict[str, str]:
        """The implementation each stage runs after `setup` (stage -> backend, e.g. ``{"rasterizer":
        "cuda"}``), for the run's log and results; empty when the method does not say."""
        return {}
