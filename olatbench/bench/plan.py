"""Plans: method × suite × scene × variant × seed -> a list of `Job`.

Config resolution order for one job (later wins; `olatbench.methods.resolve`, which also names each
value's source): the method config's defaults, the suite's ``iterations`` (or the method's own,
`MethodSpec.iterations`, when its spec fixes one), the method's preset named after the suite
(`Suite.preset`; when the method has one), or for a scene of no suite
(``run --data``, ``[suites.NAME]``) the preset derived from it when the method declares a scene
recipe (`derived_preset`; else the preset of its format, over which a user suite's own
``iterations`` win), the variant's preset, then explicit overrides (``--set KEY=VALUE``;
``--iterations N`` is exactly ``--set iterations=N``). The variant ``default`` applies no variant
preset; a variant ``a+b`` applies the presets ``a`` then ``b``. Overrides are part of the job's
variant label (``default~iterations=500,test_time_steps=50``), so they get their own folders and
report rows.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from olatbench.bench.init_points import InitPointsError, init_points_file, points_digest
from olatbench.bench.jobs import Job, code_hash, config_to_dict, data_manifest_hash
from olatbench.bench.store import job_folder
from olatbench.datasets.errors import DatasetError
from olatbench.datasets.sizes import checked_size
from olatbench.datasets.suites import Suite, get_suite
from olatbench.methods.overrides import OverrideError, check_overrides
from olatbench.methods.registry import config_class, get_spec
from olatbench.methods.resolve import DEFAULT_VARIANT, ResolvedConfig, resolve, variant_presets
from olatbench.methods.scene_presets import DerivedPreset, SceneFacts, derive_preset
from olatbench.methods.spec import MethodSpec, import_reference
from olatbench.names import did_you_mean, match_name

DATA_ENV = "OLATBENCH_DATA"


class PlanError(ValueError):
    """A plan that cannot be made (unknown method, preset, scene; missing data): one clear
    message."""


class OverridesError(PlanError):
    """A ``--set KEY=VALUE`` that cannot be used (malformed, not finite, unknown field, wrong type,
    out of range): a usage error, one message naming the field."""


@dataclass(frozen=True)
class PlanOptions:
    """Run settings that do not enter job ids (device, checkpoint cadence, components, where
    official code lives)."""

    device: str = "cpu"
    checkpoint_every: int | None = None
    checkpoint_minutes: float = 10.0
    keep_checkpoints: int = 2
    save_components: bool = False
    # `Job.novel_lights`: score under novel illumination too
    novel_lights: Mapping[str, Any] | None = None
    # official methods: --code KEY=VALUE settings
    code: Mapping[str, str] = field(default_factory=dict)
    # reuse a finished job's model for the same experiment under another variant name
    reuse: bool = True


def expand_variants(
    spec: MethodSpec, variants: Sequence[str] = (), ablation: str | None = None
) -> list[str]:
    """The variant names of a plan: ``variants`` then the method's ablation grid ``ablation``,
    deduplicated, checked against the method's presets.

    No variant and no ablation gives ``["default"]``; ``"a+b"`` names a combination of presets.
    """
    names = list(variants)
    if ablation is not None:
        if ablation not in spec.ablations:
            grids = ", ".join(sorted(spec.ablations)) or "none"
            raise PlanError(
                f"method '{spec.name}' has no ablation grid '{ablation}'"
                f"{did_you_mean(ablation, spec.ablations)}; its grids: {grids}. "
                f"See: olatbench methods show {spec.name}"
            )
        names += spec.ablations[ablation]
    try:  # "a + b" is the variant "a+b": one spelling, one folder
        parts = [variant_presets(name) for name in names]
    except ValueError as error:
        raise PlanError(f"--variant: {error}") from None
    names = list(dict.fromkeys("+".join(part) or DEFAULT_VARIANT for part in parts)) or [
        DEFAULT_VARIANT
    ]
    missing = [part for presets in parts for part in presets if part not in spec.presets]
    if missing:
        known = ", ".join(sorted(spec.presets)) or "none"
        hints = "".join(did_you_mean(part, spec.presets) for part in missing)
        raise PlanError(
            f"method '{spec.name}' has no preset {', '.join(missing)}{hints}; its presets: "
            f"{known}. See: olatbench methods show {spec.name}"
        )
    return names


def resolve_config(
    spec: MethodSpec,
    suite: Suite,
    variant: str = DEFAULT_VARIANT,
    iterations: int | None = None,
    overrides: dict[str, Any] | None = None,
    derived: DerivedPreset | None = None,
) -> Any:
    """The method's config for one suite and variant (`resolve_sources` without the sources)."""
    return resolve_sources(spec, suite, variant, iterations, overrides, derived).config


def resolve_sources(
    spec: MethodSpec,
    suite: Suite,
    variant: str = DEFAULT_VARIANT,
    iterations: int | None = None,
    overrides: dict[str, Any] | None = None,
    derived: DerivedPreset | None = None,
) -> ResolvedConfig:
    """The method's config for one suite and variant, and each field's source
    (`olatbench.methods.resolve`, the order in the module docstring); ``derived``, the preset
    derived from a scene of no suite (`derived_preset`), takes the place of the suite's preset. A
    `PlanError` names the method, the variant and what is wrong."""
    overrides = checked_overrides(spec, overrides)
    overrides = with_iterations(overrides, iterations)
    if spec.iterations == 0 and overrides.get("iterations", 0) != 0:
        raise PlanError(
            f"method '{spec.name}' learns nothing (its spec says iterations=0), so it takes no "
            f"--iterations / --set iterations (got {overrides['iterations']})"
        )
    try:
        return resolve(
            spec.name,
            config_class(spec),
            spec.presets,
            variant,
            overrides,
            suite=suite,
            own_iterations=spec.iterations,
            derived=derived,
        )
    except (KeyError, TypeError, ValueError) as error:
        raise PlanError(f"method '{spec.name}', variant '{variant}': {error}") from None


def derived_preset(
    spec: MethodSpec,
    suite: Suite,
    facts: SceneFacts | None,
    overrides: Mapping[str, Any] | None = None,
) -> DerivedPreset | None:
    """The preset derived from a scene of no suite (`olatbench.methods.scene_presets`) for a method
    that declares a scene recipe; None for a benchmark suite's scene (its preset is the paper's), a
    method without a recipe, or a scene whose folder is not there to read. The length asked for is
    ``--iterations`` / ``--set iterations``, else a user suite's own ``iterations``, else
    derived."""
    if facts is None or not suite.scene_paths or spec.scene_recipe is None:
        return None
    asked = (overrides or {}).get("iterations")
    if asked is None and suite.iterations_given:
        asked = suite.iterations
    return derive_preset(spec.scene_recipe, spec.presets[spec.scene_recipe], facts, asked)


def derived_for_folder(
    spec: MethodSpec, folder: str | Path, iterations: int | None = None
) -> DerivedPreset | None:
    """The preset ``run -m <spec> --data <folder>`` derives (``methods show --data``); None for a
    method without a scene recipe. A `DatasetError` for a folder that is not a scene."""
    from olatbench.datasets.suites import data_suites

    (suite,) = data_suites([folder])
    count, size = scene_size(folder, suite.format, suite.train_split)
    overrides = {} if iterations is None else {"iterations": iterations}
    return derived_preset(spec, suite, SceneFacts(count, *size), overrides)


def scene_size(scene_path: str | Path, fmt: str, split: str) -> tuple[int, tuple[int, int]]:
    """The number of images of ``split`` and their size (width, height) from the scene's metadata
    (no image is decoded); a scene whose images differ in size gives the largest."""
    from olatbench.datasets import load_scene

    frames = load_scene(scene_path, format=fmt).split(split)
    if not frames:
        raise PlanError(f"{scene_path}: the scene has no '{split}' images to train on")
    width = max(frame.camera.width for frame in frames)
    height = max(frame.camera.height for frame in frames)
    return len(frames), (width, height)


def check_rig(scene_path: str | Path, fmt: str, split: str) -> None:
    """Refuse, naming the scene and why, a training split whose cameras no canonical frame fits
    (`olatbench.datasets.similarity.rig_centre`: all at one point, looking outwards, or facing one
    way without near/far): such a job would train to blank renders. Reads the transforms files
    only."""
    from olatbench.datasets import load_scene
    from olatbench.datasets.similarity import RigError, canonical_frame

    frames = load_scene(scene_path, format=fmt).split(split)
    if not frames:
        # nothing to train on: said where the images are counted (scene_size) or when the job loads
        # them
        return
    try:
        canonical_frame([frame.camera for frame in frames])
    except RigError as error:
        raise PlanError(
            f"{scene_path}: {error}. olatbench trains in a frame fitted to the cameras "
            '(docs/own-data.md, "Rigs olatbench can fit")'
        ) from None


def checked_resolution(
    requested: tuple[int, int] | None,
    native: tuple[int, int] | None,
    scene: str,
    stretch: bool = False,
    upscale: bool = False,
) -> tuple[int, int] | None:
    """``--resolution`` checked against the scene's own size ``native`` (None: not known yet, e.g. a
    dry run before the data exists): a side outside `olatbench.datasets.sizes.checked_size`'s bounds
    is refused, even with ``upscale``; so are, unless asked, a size larger than the scene's
    (``upscale``) and one that changes its aspect ratio by more than a pixel's rounding
    (``stretch``). Gives back ``requested``."""
    if requested is None:
        return None
    width, height = requested
    try:
        checked_size(width, height)
    except ValueError as error:
        raise PlanError(f"--resolution {width}x{height}: {error}") from None
    if native is None:
        return requested
    own_width, own_height = native
    if not upscale and (width > own_width or height > own_height):
        raise PlanError(
            f"--resolution {width}x{height} is larger than the images of scene {scene} "
            f"({own_width}x{own_height}): they would be upsampled (add --upscale to do it anyway)"
        )
    if not stretch and abs(width * own_height - height * own_width) > max(own_width, own_height):
        raise PlanError(
            f"--resolution {width}x{height} changes the aspect ratio of scene {scene} ({own_width}x"
            f"{own_height}): its images would be squashed; keep the ratio (e.g. {width}x"
            f"{max(1, round(width * own_height / own_width))}) or add --stretch to do it anyway"
        )
    return requested


def with_iterations(overrides: Mapping[str, Any] | None, iterations: int | None) -> dict[str, Any]:
    """``overrides`` with ``--iterations N`` folded in as ``iterations=N``: one spelling, one label,
    one folder, one job id with ``--set iterations=N``. Both given and different is a
    `PlanError`."""
    merged = dict(overrides or {})
    if iterations is None:
        return merged
    given = merged.get("iterations")
    if given is not None and given != iterations:
        raise PlanError(
            f"--iterations {iterations} and --set iterations={given} disagree; give one of them"
        )
    merged["iterations"] = int(iterations)
    return merged


def checked_overrides(spec: MethodSpec, overrides: dict[str, Any] | None) -> dict[str, Any]:
    """``overrides`` fitted to the types of the method's config fields
    (`olatbench.methods.overrides`); an unknown field or a value that does not fit is one
    `PlanError` naming the field, value and accepted form."""
    try:
        return check_overrides(config_class(spec), overrides or {}, spec.name)
    except OverrideError as error:
        raise OverridesError(str(error)) from None


def parse_overrides(items: Sequence[str]) -> dict[str, Any]:
    """``["key=value", ...]`` -> {key: value}; values are read as JSON (``true``, ``50``, ``[1, 1,
    1]``), anything that is not JSON stays a string (``shadow_mode=density``, ``use_sss=False``);
    the plan then fits each to its field's type (`checked_overrides`). A number that is not finite
    (``NaN``, ``Infinity``, ``1e999``, also inside a list) is an `OverridesError`: it is no config
    value, and no results.json could hold it."""
    overrides: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise OverridesError(f"--set expects KEY=VALUE (e.g. test_time_steps=50), not {item!r}")
        try:
            value = json.loads(text, parse_constant=_not_finite, parse_float=_finite_float)
        except json.JSONDecodeError:
            value = text
        except _NotFinite as error:
            raise OverridesError(
                f"--set {item}: {error} is not a finite number; give a value such as 0.5"
            ) from None
        overrides[key.strip()] = value
    return overrides


class _NotFinite(ValueError):
    """A JSON number that is no finite float (its text is the message)."""


def _not_finite(text: str) -> float:
    raise _NotFinite(text)


def _finite_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise _NotFinite(text)
    return value


def variant_label(
    variant: str, overrides: dict[str, Any] | None, resolution: tuple[int, int] | None = None
) -> str:
    """The variant's name with its overrides and a ``--resolution`` other than the suite's:
    ``default~resolution=32x32,shadow_mode=density,test_time_steps=50``."""
    named = dict(overrides or {})
    if resolution is not None:
        named["resolution"] = f"{resolution[0]}x{resolution[1]}"
    if not named:
        return variant
    parts = ",".join(
        f"{key}={json.dumps(value, separators=(',', ':')).strip(chr(34))}"
        for key, value in sorted(named.items())
    )
    return f"{variant}~{parts}".replace("/", "_").replace(" ", "")  # one folder name


def resolve_scenes(suite: Suite, scenes: Sequence[str] = ()) -> list[str]:
    """Canonical names of the requested scenes (all of the suite's when empty); aliases accepted."""
    if not scenes:
        return list(suite.scenes)
    resolved = []
    for name in scenes:
        canonical = suite.canonical(name) or match_name(name, suite.scenes)
        if canonical is None:
            raise PlanError(
                f"suite '{suite.name}' has no scene '{name}'{did_you_mean(name, suite.scenes)}; "
                f"scenes: {', '.join(suite.scenes)}"
            )
        resolved.append(canonical)
    return list(dict.fromkeys(resolved))


def resolve_data_root(
    suite: Suite,
    data_root: str | Path | None,
    scenes: Sequence[str],
    generate: bool = True,
    progress: bool = True,
) -> Path | None:
    """The folder holding the suite's scene folders (None for a user's suite: its scenes name their
    folders).

    Suites without a generator use ``data_root``, else ``$OLATBENCH_DATA``. A suite with a
    ``generator`` (``mini``) ignores ``$OLATBENCH_DATA`` (which points at real data) and creates its
    data on first use in ``data_root`` when given, else in the generator's default cache (only the
    requested ``scenes``: the generator is called as ``generator(root, progress=...,
    scenes=[...])``). Dry runs (``generate`` False) never create data: they use it where it already
    is (``data_root``, else the generator's default folder, ``suite.generator_root``) and get None
    when it is missing. (A real run still re-renders generated data whose recipe or files no longer
    match; its job ids then differ from the dry run's.)
    """
    if suite.scene_paths:  # a user's suite: every scene names its own folder
        return None
    root = data_root
    if root is None and suite.generator is None:
        root = os.environ.get(DATA_ENV)
    if suite.generator is None:
        if root is None:
            raise PlanError(
                f"suite '{suite.name}' needs its data: pass --data-root or set {DATA_ENV}. "
                f"Try: olatbench datasets download {suite.name}"
            )
        return Path(root)
    if root is not None and _all_present(suite, Path(root), scenes):
        return Path(root)
    if not generate:
        default = (
            _import_callable(suite.generator_root)()
            if root is None and suite.generator_root
            else None
        )
        return (
            Path(default)
            if default is not None and _all_present(suite, Path(default), scenes)
            else None
        )
    return Path(
        _import_callable(suite.generator)(
            None if root is None else Path(root), progress=progress, scenes=list(scenes)
        )
    )


def _all_present(suite: Suite, root: Path, scenes: Sequence[str]) -> bool:
    try:
        for scene in scenes:
            suite.scene_path(root, scene)
    except DatasetError:
        return False
    return True


def _import_callable(reference: str) -> Callable[..., Any]:
    import importlib

    module_name, _, attribute = reference.partition(":")
    return getattr(importlib.import_module(module_name), attribute)


def official_settings(
    spec: MethodSpec, options: Mapping[str, str], required: bool = True
) -> dict[str, Any]:
    """Where an official method's code lives and runs (`olatbench.methods.official.settings`:
    ``options``, then ``olatbench.toml``, then environment variables), as job data. A code that
    cannot be fed olatbench's data is a `PlanError` giving the reason; so are missing settings when
    ``required`` (not for dry runs)."""
    from olatbench.methods.official.settings import (
        SettingsError,
        env_name,
        pin_problem,
        resolve_settings,
    )

    code = import_reference(spec.implementation)
    if not code.runnable:
        raise PlanError(
            f"method '{spec.name}' cannot be run: {code.unsupported}. See: olatbench methods show "
            f"{spec.name}"
        )
    try:
        settings = resolve_settings(spec.name, options)
    except SettingsError as error:
        raise PlanError(str(error)) from None
    problems = settings.problems() if required else []
    if required and not problems and spec.source is not None:
        problems = [
            problem
            for problem in (pin_problem(str(settings.checkout), spec.source.commit),)
            if problem
        ]
    if problems:
        raise PlanError(
            f"method '{spec.name}' runs the authors' code, and where it lives is not set up: "
            f"{'; '.join(problems)}. Set them with --code KEY=VALUE, in olatbench.toml "
            f"([official.{spec.name}]) or as environment variables "
            f"({env_name(spec.name, 'checkout')}, ...); see docs/official.md"
        )
    return settings.to_json()


def load_method_class(job: Job) -> type:
    """The class a job runs: from its import reference (works in fresh worker processes)."""
    return import_reference(job.method_ref)


def make_plan(
    method: str,
    suite: str | Suite,
    out: str | Path,
    scenes: Sequence[str] = (),
    variants: Sequence[str] = (),
    ablation: str | None = None,
    seeds: int = 1,
    iterations: int | None = None,
    resolution: tuple[int, int] | None = None,
    data_root: str | Path | None = None,
    options: PlanOptions | None = None,
    generate: bool = True,
    progress: bool = True,
    overrides: dict[str, Any] | None = None,
    init_points: str | Path | None = None,
    stretch: bool = False,
    upscale: bool = False,
) -> list[Job]:
    """Expand one method on one suite into jobs (scene-major, then variant, then seed).

    ``resolution`` (width, height) overrides the suite's (checked by `checked_resolution`;
    ``stretch`` and ``upscale`` allow what it refuses) and, when it differs from the suite's, is
    named in the variant's label (``default~resolution=32x32``: its own folder beside the suite's
    size); ``overrides`` are config values applied to every variant (and named in its label). A
    scene of no suite gets the method's derived preset (`derived_preset`) in place of its format's.
    ``generate=False`` (dry runs) never creates a generator suite's data: when it is missing, jobs
    have ``data_manifest=None`` and no id. A method with the ``init_points`` capability starts from
    ``init_points`` (a point PLY; named in the label as ``init_points=<file stem>``) or else from a
    scene folder's ``points3d.ply`` (`olatbench.bench.init_points`); the file's digest enters the
    job id.
    """
    options = options or PlanOptions()
    suite = get_suite(suite) if isinstance(suite, str) else suite
    try:
        spec = get_spec(method)
    except KeyError as error:
        raise PlanError(f"{error.args[0]}. See: olatbench methods list") from None
    except ImportError as error:
        raise PlanError(str(error)) from None
    method = spec.name  # "SSDGS" plans the ssdgs jobs
    if seeds < 1:
        raise PlanError(f"--seeds must be at least 1, not {seeds}")
    if init_points is not None and "init_points" not in spec.capabilities:
        raise PlanError(
            f"method '{spec.name}' cannot start from a point cloud (--init-points); methods that "
            "can declare the capability init_points (olatbench methods show METHOD)"
        )
    from olatbench.metrics.protocols import get_protocol

    try:
        protocol = get_protocol(suite.protocol)
    except ValueError as error:
        raise PlanError(f"{suite.source or f'suite {suite.name}'}: protocol: {error}") from None
    if options.code and spec.kind != "official":
        raise PlanError(
            f"--code settings are for official implementations (*-official), not for '{method}'"
        )
    official = (
        official_settings(spec, options.code, required=generate)
        if spec.kind == "official"
        else None
    )
    variant_names = expand_variants(spec, variants, ablation)
    scene_names = resolve_scenes(suite, scenes)
    root = resolve_data_root(suite, data_root, scene_names, generate=generate, progress=progress)
    # typed before they name the variant (use_sss=False -> false); --iterations N is --set
    # iterations=N
    overrides = checked_overrides(spec, with_iterations(overrides, iterations))
    code = code_hash(spec.implementation)  # located, not imported: dry runs need no torch
    suite_configs = {
        variant: resolve_sources(spec, suite, variant, overrides=overrides)
        for variant in variant_names
    }
    jobs = []
    for scene in scene_names:
        scene_path = (
            suite.scene_path(root, scene) if root is not None or suite.scene_paths else None
        )
        manifest = data_manifest_hash(scene_path) if scene_path is not None else None
        try:
            points = (
                init_points_file(scene_path, init_points)
                if "init_points" in spec.capabilities
                else None
            )
        except InitPointsError as error:
            raise PlanError(str(error)) from None
        named = {"init_points": Path(init_points).stem} if init_points is not None else {}
        if scene_path is not None and suite.frame == "fitted" and spec.kind != "official":
            check_rig(scene_path, suite.format, suite.train_split)
        count, native = (
            scene_size(scene_path, suite.format, suite.train_split)
            if scene_path is not None and (resolution is not None or suite.scene_paths)
            else (0, None)
        )
        size = checked_resolution(resolution, native, scene, stretch, upscale) or suite.resolution
        if size == native and suite.resolution is None:
            size = None  # the scene's own size, asked for: the same job as not asking
        facts = SceneFacts(count, *(size or native)) if native and suite.scene_paths else None
        derived = derived_preset(spec, suite, facts, overrides)
        configs = (
            suite_configs
            if derived is None
            else {
                variant: resolve_sources(spec, suite, variant, overrides=overrides, derived=derived)
                for variant in variant_names
            }
        )
        for variant in variant_names:
            for seed in range(seeds):
                label = variant_label(
                    variant,
                    {**(overrides or {}), **named},
                    size if size != suite.resolution else None,
                )
                try:
                    folder = job_folder(out, suite.name, method, label, scene, seed)
                except ValueError as error:
                    raise PlanError(str(error)) from None
                job = Job(
                    method=method,
                    method_ref=spec.implementation,
                    suite=suite.name,
                    scene=scene,
                    variant=label,
                    seed=seed,
                    config=config_to_dict(configs[variant].config),
                    scene_path=str(scene_path) if scene_path else "",
                    scene_format=suite.format,
                    colourspace=suite.colourspace,
                    resolution=size,
                    train_split=suite.train_split,
                    test_split=suite.test_split,
                    protocol=protocol.id,
                    protocol_version=int(protocol.version),
                    data_manifest=manifest,
                    code=code,
                    folder=str(folder),
                    device=options.device,
                    checkpoint_every=options.checkpoint_every,
                    checkpoint_minutes=options.checkpoint_minutes,
                    keep_checkpoints=options.keep_checkpoints,
                    save_components=options.save_components,
                    official=official,
                    reuse=options.reuse,
                    novel_lights=dict(options.novel_lights)
                    if options.novel_lights is not None
                    else None,
                    init_points=str(points) if points else "",
                    init_points_digest=points_digest(points) if points else None,
                    # the authors' code: as is
                    frame="dataset" if spec.kind == "official" else suite.frame,
                    derived=dict(derived.reasons) if derived is not None else {},
                    ablation=spec.ablation_of(variant, ablation),
                    sources=dict(configs[variant].sources),
                )
                jobs.append(job.with_id() if manifest is not None else job)
    return jobs
