"""How to run one official implementation, as data (stdlib only): `OfficialCode` and the config of
its jobs.

An `OfficialCode` names the olatbench format the authors' loader reads, the commands to run in order
(the script first; the launcher of `olatbench.methods.official.settings` puts the interpreter in
front) with the placeholders filled per job, where the test renders land and which frame each shows,
per-scene flags, the training steps and milestones, and how a run shorter than the scripts' scales
their schedule. docs/official.md ("Adding an official implementation") describes each field.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import ClassVar

from olatbench.methods.ranges import AT_LEAST_ONE, Range, check_ranges
from olatbench.methods.run_length import scaled_steps

SUITE_ARGS = "{*suite_args}"
ANY_SUITE = "*"
# the converted test split, as the official loaders read it
LOADER_ORDER = "{scene}/transforms_test.json"
TRAIN_STEP = "train"  # the train step of a code that names no others (OfficialCode.train_steps)
ARGUMENT_FIELDS = ("preset_args", "train_args", "render_args")  # OfficialConfig's argument lists


@dataclass(frozen=True)
class OfficialConfig:
    """The config of an official method's jobs (enters the job id, as every config does)."""

    ranges: ClassVar[dict[str, Range]] = {
        "iterations": AT_LEAST_ONE,
        "reference_iterations": AT_LEAST_ONE,
        "init_points": AT_LEAST_ONE,
    }

    iterations: int = 100_000
    """Training iterations handed to the official script (``{iterations}``)."""
    reference_iterations: int | None = None
    """Length the scripts' schedule flags are written for; set, they are scaled by ``iterations`` /
    this (module docstring). None: the flags as the scripts have them."""
    preset_args: tuple[str, ...] = ()
    """Train flags a preset sets (the mini presets: the native mini presets' Gaussian budget,
    densification window and opacity reset), applied after the scene's flags and before the schedule
    is scaled: iteration-valued ones are given at ``reference_iterations`` and scaled with the rest,
    unlike ``train_args`` (passed as given)."""
    init_points: int | None = None
    """Initial points olatbench writes for the loader (seeded by the job); None: the loader's
    own."""
    train_args: tuple[str, ...] = ()
    """Extra arguments appended to the train command (``--set train_args='["--foo","1"]'``)."""
    render_args: tuple[str, ...] = ()
    """Extra arguments appended to the render command."""

    def __post_init__(self) -> None:
        # a job.json or --set gives lists: the config holds tuples either way
        for name in ARGUMENT_FIELDS:
            object.__setattr__(self, name, tuple(getattr(self, name)))
        check_ranges(self, "official method")


def _frozen(mapping: Mapping) -> Mapping:
    return MappingProxyType(
        {
            key: (_frozen(value) if isinstance(value, Mapping) else value)
            for key, value in mapping.items()
        }
    )


@dataclass(frozen=True)
class SceneArgs:
    """Flags the authors' script gives one scene of a suite for one step, instead of (or on top of)
    the suite's."""

    suite: str
    scene: str  # canonical scene name (`olatbench.datasets.suites`)
    step: str
    args: tuple[str, ...]  # "--flag value" pairs or bare "--switch"es
    source: str  # where the pinned commit says so: "real_train.sh:306-336"


def last_index(argv: list[str], flag: str) -> int | None:
    """The position of the last ``flag`` in ``argv`` (None when absent)."""
    return max((i for i, arg in enumerate(argv) if arg == flag), default=None)


def apply_scene_args(argv: list[str], args: tuple[str, ...]) -> list[str]:
    """``argv`` with each ``--flag [value]`` of ``args`` replacing that flag's value
    (its last occurrence), or appended when ``argv`` lacks the flag."""
    out = list(argv)
    index = 0
    while index < len(args):
        flag = args[index]
        has_value = index + 1 < len(args) and not args[index + 1].startswith("--")
        value = [args[index + 1]] if has_value else []
        index += 1 + len(value)
        where = last_index(out, flag)
        if where is None:
            out += [flag, *value]
        elif value and where + 1 < len(out) and not out[where + 1].startswith("--"):
            out[where + 1] = value[0]
        elif value:
            out.insert(where + 1, value[0])
    return out


@dataclass(frozen=True)
class OfficialCode:
    """How to run one official implementation (module docstring)."""

    name: str
    paper: str
    # (step, argv without interpreter), run in order
    commands: tuple[tuple[str, tuple[str, ...]], ...]
    renders: str  # path pattern of the test render of frame {index}
    data_formats: Mapping[str, str] = field(default_factory=lambda: {ANY_SUITE: "nrhints"})
    # suite -> what the PNGs hold (srgb)
    render_colourspace: Mapping[str, str] = field(default_factory=dict)
    # suite -> step -> args
    suite_args: Mapping[str, Mapping[str, tuple[str, ...]]] = field(default_factory=dict)
    # extra environment variables of every command
    env: Mapping[str, str] = field(default_factory=dict)
    # flag -> transforms file then rendered in order
    render_orders: Mapping[str, str] = field(default_factory=dict)
    scene_args: tuple[SceneArgs, ...] = ()  # the scripts' per-scene flags (module docstring)
    # the loader reads one camera (intrinsics, size, near/far) for all frames
    single_camera_model: bool = False
    # the loader opens transforms_val.json (written from the test split if absent)
    needs_val_split: bool = False
    # train flag -> parser default (scaled runs)
    schedule_flags: Mapping[str, int] = field(default_factory=dict)
    # where in the scene folder the loader reads its initial points ("": it reads none)
    point_cloud: str = ""
    unsupported: str = ""  # why olatbench's scenes cannot be fed to this code ("" = runnable)
    # where the render script writes the ground truth of render {index} ("": none)
    render_ground_truths: str = ""
    # the training commands: scaled, timed, given train_args
    train_steps: tuple[str, ...] = (TRAIN_STEP,)
    # placeholder -> iterations at the scripts' length
    milestones: Mapping[str, int] = field(default_factory=dict)
    # (what, where the pinned commit says so), for `methods show`
    sources: tuple[tuple[str, str], ...] = ()
    # train flags for a white background (scenes of one's own)
    white_background_args: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not self.commands and not self.unsupported:
            raise ValueError(f"official code {self.name!r}: no commands")
        steps = [step for step, _ in self.commands]
        if len(set(steps)) != len(steps):
            raise ValueError(f"official code {self.name!r}: step names repeat: {steps}")
        unknown = sorted(set(self.train_steps) - set(steps))
        if self.commands and unknown:
            raise ValueError(
                f"official code {self.name!r}: train_steps {unknown} are no step of {steps}"
            )
        for attribute in (
            "data_formats",
            "render_colourspace",
            "suite_args",
            "env",
            "render_orders",
            "schedule_flags",
            "milestones",
        ):
            object.__setattr__(self, attribute, _frozen(getattr(self, attribute)))

    @property
    def runnable(self) -> bool:
        return not self.unsupported

    def data_format(self, suite: str) -> str:
        """The olatbench format the scene is written in for ``suite``."""
        return self.data_formats.get(suite, self.data_formats.get(ANY_SUITE, "nrhints"))

    def colourspace_for(self, suite: str) -> str:
        """What the render PNGs hold for ``suite`` (``srgb`` unless the code writes e.g.
        ``x^(1/2.2)``)."""
        return self.render_colourspace.get(suite, self.render_colourspace.get(ANY_SUITE, "srgb"))

    def args_for(self, suite: str, step: str) -> tuple[str, ...]:
        """What ``{*suite_args}`` expands to for ``suite`` and ``step``."""
        block = self.suite_args.get(suite, self.suite_args.get(ANY_SUITE, {}))
        return tuple(block.get(step, ()))

    def args_for_scene(self, suite: str, scene: str | None, step: str) -> tuple[str, ...]:
        """The per-scene flags of ``scene`` (canonical name) for ``step``
        (empty for other scenes)."""
        return tuple(
            arg
            for entry in self.scene_args
            if (entry.suite, entry.scene, entry.step) == (suite, scene, step)
            for arg in entry.args
        )

    def scaled_schedule(
        self, argv: list[str], iterations: int, reference_iterations: int
    ) -> list[str]:
        """``argv`` with each flag of ``schedule_flags`` (its last occurrence in ``argv``, else the
        parser's default) taken from a run of ``reference_iterations`` to one of ``iterations``
        (`scaled_steps`, the rule the native methods apply to their iteration-valued fields)."""
        scaled: list[str] = []
        for flag, default in self.schedule_flags.items():
            where = last_index(argv, flag)
            value = int(argv[where + 1]) if where is not None else default
            scaled += [flag, str(scaled_steps(value, iterations, reference_iterations))]
        return apply_scene_args(argv, tuple(scaled))

    def milestone_values(self, iterations: int, reference_iterations: int | None) -> dict[str, int]:
        """The ``milestones`` for a run of ``iterations`` steps: as the scripts write them, or
        scaled from a run of ``reference_iterations`` (`scaled_steps`); `ValueError` when one is not
        between 1 and ``iterations`` - 1 (a stage would be empty)."""
        values = {
            name: value
            if reference_iterations is None
            else scaled_steps(value, iterations, reference_iterations)
            for name, value in self.milestones.items()
        }
        for name, value in values.items():
            if not 1 <= value < iterations:
                scale = (
                    ""
                    if reference_iterations is None
                    else f" × {iterations}/{reference_iterations}"
                )
                raise ValueError(
                    f"{name} = {value} (the scripts' {self.milestones[name]}{scale}) must lie "
                    f"between 1 and iterations - 1 = {iterations - 1}: run more iterations, or "
                    "set reference_iterations to scale it"
                )
        return values

    def command(
        self,
        step: str,
        argv: tuple[str, ...],
        values: Mapping[str, str],
        suite: str,
        extra: tuple[str, ...] = (),
        scene: str | None = None,
        schedule_lengths: tuple[int, int] | None = None,
        preset_args: tuple[str, ...] = (),
    ) -> list[str]:
        """One command's arguments with the placeholders filled, ``scene``'s own flags and then
        ``preset_args`` applied, the train step's schedule scaled from ``schedule_lengths`` =
        (iterations, reference_iterations) (when given; `scaled_schedule`) and ``extra`` appended
        (as given: a flag the user sets is never scaled)."""
        filled: list[str] = []
        for arg in argv:
            if arg == SUITE_ARGS:
                filled.extend(self.args_for(suite, step))
                continue
            try:
                filled.append(arg.format_map(values))
            except KeyError as error:
                raise ValueError(
                    f"official code {self.name!r}, step {step!r}: unknown placeholder {error} in "
                    f"{arg!r}; known: {', '.join(sorted(values))}, {SUITE_ARGS}"
                ) from None
        filled = apply_scene_args(filled, self.args_for_scene(suite, scene, step))
        if step in self.train_steps:
            filled = apply_scene_args(filled, preset_args)
            if schedule_lengths is not None:
                filled = self.scaled_schedule(filled, *schedule_lengths)
        return filled + list(extra)

    def render_order(self, commands: list[list[str]]) -> str:
        """The transforms file (pattern) whose frame order numbers the renders, given the filled-in
        commands."""
        flags = {arg for argv in commands for arg in argv}
        return next(
            (path for flag, path in self.render_orders.items() if flag in flags), LOADER_ORDER
        )

    def fits_test_views(self, suite: str, render_args: tuple[str, ...] = ()) -> bool:
        """Whether a job on ``suite`` scores test views whose cameras and lights its training fitted
        to the test images: its render command (its own flags, the suite's, ``render_args``) carries
        a flag of ``render_orders`` (SSD-GS's and GS³'s ``--opt_pose``). The runner records it in
        results.json (``evaluation.test_pose_fitting``) and the reports read it."""
        own = [arg for step, argv in self.commands if step == "render" for arg in argv]
        return (
            self.render_order([[*own, *self.args_for(suite, "render"), *render_args]])
            != LOADER_ORDER
        )

    def describe(self) -> list[str]:
        """The commands and render pattern as text lines, placeholders kept
        (``olatbench methods show``)."""
        if not self.commands:
            return []
        lines = [f"{step}: <launcher> {' '.join(argv)}" for step, argv in self.commands]
        suites = sorted(
            set(self.suite_args) | set(self.data_formats) | set(self.render_colourspace)
        )
        for suite in suites:
            args = "; ".join(
                f"{step} {' '.join(self.args_for(suite, step))}"
                for step, _ in self.commands
                if self.args_for(suite, step)
            )
            lines.append(
                f"suite {suite}: data written as {self.data_format(suite)}, renders hold "
                f"{self.colourspace_for(suite)}" + (f", {SUITE_ARGS} = {args}" if args else "")
            )
        for entry in self.scene_args:
            lines.append(
                f"scene {entry.suite}/{entry.scene}: {entry.step} {' '.join(entry.args)} "
                f"({entry.source})"
            )
        if self.schedule_flags:
            lines.append(
                "scaled with reference_iterations (defaults in brackets): "
                + " ".join(f"{flag} [{default}]" for flag, default in self.schedule_flags.items())
            )
        if self.milestones:
            lines.append(
                "milestones (scaled with reference_iterations): "
                + " ".join(f"{{{name}}} = {value}" for name, value in self.milestones.items())
            )
        if self.white_background_args:
            lines.append(
                "a scene of your own with a white background: train "
                + " ".join(self.white_background_args)
            )
        if self.point_cloud:
            lines.append(f"init_points: written to {{scene}}/{self.point_cloud}")
        lines.append(f"renders: {self.renders}")
        orders = "".join(f"; with {flag}: of {path}" for flag, path in self.render_orders.items())
        lines.append(
            f"render i shows the i-th frame of {LOADER_ORDER}{orders} (paired by "
            "img_path/file_path)"
        )
        if self.env:
            lines.append("environment: " + " ".join(f"{k}={v}" for k, v in self.env.items()))
        lines += [f"source of {what}: {where}" for what, where in self.sources]
        return lines
