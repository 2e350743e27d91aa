"""The SSD-GS configuration: one flat dataclass, every field JSON-serialisable.

Iteration-valued fields (schedule thresholds, learning-rate decay, densification windows, opacity
reset) are given for ``reference_iterations`` total steps and scale proportionally when
``iterations`` differs (`SSDGSConfig.steps`). The densification *interval* is a cadence and does not
scale. Defaults are the paper's full model (Composition D, Schedule I) with the official code's
values where the paper is silent; `olatbench.methods.ssdgs.presets` adapts them per suite.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar

from olatbench.methods.ranges import AT_LEAST_ONE, NON_NEGATIVE, POSITIVE, RATE, UNIT, Range
from olatbench.methods.shading.config import ShadingConfig
from olatbench.methods.ssdgs.schedule import SCHEDULES, Schedule, get_schedule

_CHOICES = {
    "diffuse_cosine": ("smooth", "clamped"),
    "shading_frame": ("min_scale", "learned"),
    "asg_form": ("xu", "official"),
    "dipole_virtual_factor": ("jensen", "official"),
    "refinement_lr_clock": ("start", "absolute"),
    "light_weight_accumulation": ("always", "near_cap"),
    "test_pose_fitting": ("none", "interleaved"),
    "shadow_input_bias": ("vector", "padded_ones"),
    # shading.shadow_mlp.INPUT_BIASES (which imports torch)
    "schedule_counting": ("zero_based", "official"),
}


@dataclass
class SSDGSConfig(ShadingConfig):
    """All knobs of SSD-GS (see docs/ssdgs.md for each one's origin in the paper or the official
    code); the fields every Gaussian method shares and those of the shared shading blocks come from
    `ShadingConfig`; those redeclared here have SSD-GS's defaults."""

    label: ClassVar[str] = "SSD-GS"
    iteration_fields: ClassVar[tuple[str, ...]] = (
        *ShadingConfig.iteration_fields,
        "mlp_lr_decay_from",
        "mlp_lr_max_steps",
        "refinement_lr_max_steps",
        "refine_camera_from",
        "refine_light_from",
        "camera_lr_delay_steps",
        "light_lr_delay_steps",
    )
    ranges: ClassVar[dict[str, Range]] = {
        "dipole_eta": POSITIVE,
        "sss_hidden": AT_LEAST_ONE,
        "sss_layers": AT_LEAST_ONE,
        "sss_last_hidden": AT_LEAST_ONE,
        "sss_freqs": NON_NEGATIVE,
        "shadow_freqs": NON_NEGATIVE,
        "background": UNIT,
        "mlp_lr_init": RATE,
        "mlp_lr_final": RATE,
        "mlp_lr_decay_from": NON_NEGATIVE,
        "mlp_lr_max_steps": AT_LEAST_ONE,
        "camera_lr_init": RATE,
        "camera_lr_final": RATE,
        "light_lr_init": RATE,
        "light_lr_final": RATE,
        "refinement_lr_max_steps": AT_LEAST_ONE,
        "refine_camera_from": NON_NEGATIVE,
        "refine_light_from": NON_NEGATIVE,
        "camera_lr_delay_steps": NON_NEGATIVE,
        "camera_lr_delay_mult": NON_NEGATIVE,
        "light_lr_delay_steps": NON_NEGATIVE,
        "light_lr_delay_mult": NON_NEGATIVE,
        "test_time_steps": AT_LEAST_ONE,
    }

    iterations: int = 100_000
    reference_iterations: int = 100_000
    schedule: str = "I"
    # How the schedule's term thresholds are read: "zero_based", a term is on from step = its
    # (scaled) threshold; "official", the SSS and specular terms one step earlier, as the authors'
    # 1-based iteration counter tests `iteration < scatter_warmup_step` and `iteration <
    # specular_freeze_step + fit_linear_step` (train.py:131-132: on at iteration = threshold, our
    # step threshold - 1). The shadow term (`iteration <= unfreeze_iterations`, train.py:133) and
    # the freezes (applied after the update of iteration = threshold) agree either way.
    schedule_counting: str = "zero_based"
    # Composition (ablations A-F) and the shadow-on-SSS variant.
    use_shadow: bool = True
    use_sss: bool = True
    use_specular: bool = True
    shadow_on_sss: bool = False
    # Shading.
    diffuse_cosine: str = "smooth"
    shading_frame: str = "min_scale"
    orient_normals: bool = True
    asg_form: str = "xu"
    # Lobe parameters held by the schedule's "asg_lobes" freeze: True, every one (frames, widths
    # and, in the "official" form, σ: our reading of the paper); False, σ keeps training (the
    # official code freezes only asg_scales and asg_rotation until asg_freeze_step).
    asg_freeze_sigma: bool = True
    dipole_eta: float = 1.3
    dipole_virtual_factor: str = "jensen"
    sss_hidden: int = 256
    sss_layers: int = 6
    # the last hidden layer's width (None: sss_hidden; the official code: 128)
    sss_last_hidden: int | None = None
    sss_freqs: int = 4
    shadow_freqs: int = 3
    # The shadow network's first-layer bias: "vector", one bias vector; "padded_ones",
    # tiny-cuda-nn's layout (the input padded with ones to a multiple of 16, their weights the bias,
    # each trained on its own: the official code). `olatbench.methods.shading.shadow_mlp`.
    shadow_input_bias: str = "vector"
    clamp_output: bool = True
    # Size.
    max_gaussians: int | None = 550_000
    background: tuple[float, float, float] | None = None  # None: the training views' background
    # Learning rates (Adam, eps 1e-15). Decays are exponential (3DGS) from `*_decay_from` over
    # `*_max_steps`.
    position_lr_max_steps: int = 70_000
    mlp_lr_init: float = 1e-3
    mlp_lr_final: float = 1e-5
    mlp_lr_decay_from: int = 50_000
    mlp_lr_max_steps: int = 50_000
    # Densification window (3DGS).
    densify_until: int = 90_000
    # Camera-pose and light-position refinement (real data).
    refine_camera: bool = False
    refine_light: bool = False
    camera_lr_init: float = 1e-3
    camera_lr_final: float = 1e-5
    light_lr_init: float = 1e-3
    light_lr_final: float = 5e-5
    refinement_lr_max_steps: int = 80_000
    # Where refinement starts (iterations at reference_iterations; None: with the schedule's shadow
    # / specular phase) and how its rates decay: "start" counts the decay from the start, "absolute"
    # from iteration 0 as the official code (whose rates are 0 before the start and then the 3DGS
    # curve at the absolute iteration, with a sine warm-up from *_delay_mult over *_delay_steps).
    refine_camera_from: int | None = None
    refine_light_from: int | None = None
    refinement_lr_clock: str = "start"
    camera_lr_delay_steps: int = 0
    camera_lr_delay_mult: float = 1.0
    light_lr_delay_steps: int = 0
    light_lr_delay_mult: float = 1.0
    # Order of density control and the Adam update: False, update then densify; True, densify first
    # as the official code (its surgery drops the gradients, so a densified parameter skips that
    # step's update).
    densify_before_update: bool = False
    # When the light-view weight (the cap's priority) is accumulated: "always", or "near_cap" as the
    # official code (only once a densification has left more than 95 % of max_gaussians, until
    # densify_until).
    light_weight_accumulation: str = "always"
    # Test-time refinement: fit each test view's pose / light (what refine_camera / refine_light
    # switch on) to its image with the model frozen, Adam at camera_lr_init / light_lr_init, before
    # rendering it for scoring.
    test_time_refinement: bool = False
    test_time_steps: int = 100
    # The official real-data protocol: "interleaved" fits each *test* view's pose / light offsets
    # during training (after every training epoch, one pass over the test views in which only their
    # offsets get gradients) and scores the test images rendered with them; recorded in results.json
    # and footnoted by the reports.
    test_pose_fitting: str = "none"

    def __post_init__(self) -> None:
        super().__post_init__()
        for name, allowed in _CHOICES.items():
            if getattr(self, name) not in allowed:
                raise ValueError(
                    f"SSD-GS config: {name} must be one of {allowed}, not {getattr(self, name)!r}"
                )
        if self.schedule not in SCHEDULES:
            raise ValueError(
                f"SSD-GS config: schedule must be one of {sorted(SCHEDULES)}, not {self.schedule!r}"
            )
        if self.background is not None:
            self.background = tuple(float(v) for v in self.background)  # type: ignore[assignment]
        if self.test_time_refinement and not (self.refine_camera or self.refine_light):
            raise ValueError(
                "SSD-GS config: test_time_refinement refines what refine_camera / refine_light "
                "switch on; enable at least one of them (the nrhints and sssgs presets do)"
            )
        if self.test_pose_fitting != "none" and not (self.refine_camera or self.refine_light):
            raise ValueError(
                "SSD-GS config: test_pose_fitting fits what refine_camera / refine_light switch "
                "on; enable at least one of them"
            )

    def resolved_schedule(self) -> Schedule:
        """The schedule with its thresholds scaled to this run's length (and read as
        ``schedule_counting`` says)."""
        schedule = get_schedule(self.schedule, self.reference_iterations, self.iterations)
        if self.schedule_counting == "zero_based":
            return schedule
        earlier = {
            term: max(0, step - 1) if term in ("sss", "specular") else step
            for term, step in schedule.enable.items()
        }
        return replace(schedule, enable=earlier)

    def refinement_starts(self) -> dict[str, int]:
        """The first step of camera and light refinement in this run (``{"camera": ..., "light":
        ...}``): ``refine_camera_from`` / ``refine_light_from`` scaled to the run's length, or where
        None the step the schedule starts it (with the shadow / specular phase)."""
        schedule = self.resolved_schedule()
        return {
            "camera": schedule.refine_camera_from
            if self.refine_camera_from is None
            else self.steps(self.refine_camera_from),
            "light": schedule.refine_light_from
            if self.refine_light_from is None
            else self.steps(self.refine_light_from),
        }
