"""The ``results.json`` schema: written by ``olatbench run`` (one per job) and
``olatbench evaluate``, read by reports.

`Results` and its nested TypedDicts are the schema (version 2); `validate_results` checks a file
against them, naming the key and the value found; `upgrade_results` reads version-1 files;
`read_results` / `write_results` read and write (atomically) a validated file. docs/runner.md
("results.json") says what each key holds.
"""

import functools
import math
import sys
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any, Literal, TypedDict

from olatbench.atomic import write_json
from olatbench.datasets.jsontext import parse_json
from olatbench.metrics.protocols import get_protocol

if sys.version_info >= (3, 11):
    from typing import NotRequired, get_type_hints
else:  # pragma: no cover
    # Python 3.10: typing's get_type_hints would keep typing_extensions' NotRequired
    from typing_extensions import NotRequired, get_type_hints

# The schema as types (no `from __future__ import annotations` here: the TypedDicts'
# required/optional keys stay introspectable at run time). New keys that old files lack are
# `NotRequired`.

MetricValues = dict[str, "float | None"]  # psnr, ssim, lpips[, lpips_alex, lpips_vgg]


class ResultsJob(TypedDict):
    id: str
    method: str
    variant: str
    suite: str
    scene: str
    seed: int
    config: dict[str, Any]  # the resolved method config (dataclasses.asdict)
    # (width, height) trained and scored at; None: native; absent: older
    resolution: NotRequired[list[int] | None]


class ResultsProtocol(TypedDict):
    id: str
    version: int
    definition: NotRequired[dict[str, Any]]  # the protocol's full definition (evaluate writes it)


class SplitMetrics(TypedDict):
    mean: MetricValues
    per_image: dict[str, MetricValues]  # frame id -> values


class Timing(TypedDict):
    started: NotRequired[str | None]  # UTC ISO 8601 (schema 2)
    finished: NotRequired[str | None]
    train_seconds: float | None
    render_fps: float | None


class Resources(TypedDict):
    device: str
    peak_rss_mb: float
    cuda_peak_mb: float | None
    # stage -> implementation (olatbench.methods.backends); done runs only
    backends: NotRequired[dict[str, str]]


class CpuIdentity(TypedDict):
    model: str | None
    cores: int | None  # physical
    threads: int | None  # logical, the whole machine
    usable_threads: int | None  # this process's CPU affinity


class GpuIdentity(TypedDict):
    index: int
    name: str
    memory_mb: float


class Hardware(TypedDict):
    machine: str  # platform.machine(): x86_64, arm64, ...
    cpu: CpuIdentity
    gpus: list[GpuIdentity]
    # olatbench.numerics.cpu_numerics(): torch_cpu_capability, threads, ...
    numerics: NotRequired[dict[str, Any]]


class ReusedModel(TypedDict):
    job_id: str
    folder: str  # relative to the job folder


class ModelInfo(TypedDict):
    iterations: int
    num_gaussians: int | None
    # the finished job of the same experiment whose model this is
    reused_from: NotRequired[ReusedModel | None]


class Hashes(TypedDict):
    data_manifest: str | None
    config: str | None
    code: str | None
    # mini only: data identical to the packaged reference
    data_matches_reference: NotRequired[bool | None]
    checkpoint: NotRequired[str | None]  # sha256 of the final checkpoint (schema 2)


class ScoredFile(TypedDict):
    render: str
    render_sha256: str
    ground_truth: str | None
    ground_truth_sha256: str | None


class EvaluationSource(TypedDict):
    predictions: str
    scene: dict[str, str]  # name, format, root
    split: str
    colourspace: str
    png_space: str


class Evaluation(TypedDict):
    test_time_refinement: dict[str, Any] | None  # {"split", "seconds", "frames": {frame id: {...}}}
    # {"mode", "split", "frames": {frame id: {...}}}
    test_pose_fitting: NotRequired[dict[str, Any] | None]


class NovelLightsOptions(TypedDict):
    samples: int | None  # the environment maps' sample count; None: each lighting file's own
    views: int | None  # test frames scored per condition; None: all


class ConditionMetrics(TypedDict):
    mean: MetricValues
    per_image: dict[str, MetricValues]  # frame id -> values
    # the point and directional lights the condition was drawn as (one render each; 3DGS: one)
    lights: int


class NovelLights(TypedDict):
    protocol: ResultsProtocol  # olatbench-v1-novel-lights
    split: str  # the split whose cameras were rendered (the job's test split)
    options: NovelLightsOptions
    conditions: dict[str, ConditionMetrics]  # condition -> block
    mean: MetricValues  # per metric, the mean of the conditions' means
    seconds: float


class ResultsFailure(TypedDict):
    type: str
    message: str


class OfficialCommand(TypedDict):
    step: str
    argv: list[str]
    command: str  # the shell form of argv
    cwd: str
    exit_code: int | None  # None: did not finish (timed out)
    seconds: float | None


class OfficialProvenance(TypedDict):
    repository: str | None  # "owner/name" on GitHub
    pinned_commit: str | None  # the commit the method's spec was written against
    status: str | None  # "verified" | "unverified" | "no public code"
    commit: str | None  # the commit checked out when the job ran (None: not a git checkout)
    local_changes: bool | None
    matches_pin: bool | None
    settings: dict[str, Any]  # checkout, launcher, timeout, device and where each came from
    # "cuda" (the authors' code as written) or "cpu" (run with olatbench's stand-ins)
    device: NotRequired[str]
    # the modules replaced by olatbench's CPU stand-ins (device "cpu")
    standins: NotRequired[list[str]]
    commands: list[OfficialCommand]


class Results(TypedDict):
    """One results.json (schema version 2): the keys of the module docstring."""

    schema_version: int
    kind: Literal["run", "evaluate"]
    status: Literal["done", "failed"]
    job: ResultsJob | None  # None for kind "evaluate"
    protocol: ResultsProtocol
    metrics: dict[str, SplitMetrics]  # split -> block
    timing: NotRequired[Timing]
    resources: NotRequired[Resources]
    hardware: NotRequired[Hardware]
    model: NotRequired[ModelInfo | None]
    versions: NotRequired[dict[str, str | None]]
    hashes: NotRequired[Hashes]
    files: NotRequired[dict[str, dict[str, ScoredFile]]]  # split -> frame id -> scored files
    source: NotRequired[EvaluationSource | None]
    evaluation: NotRequired[Evaluation]
    error: NotRequired[ResultsFailure | None]
    method_kind: NotRequired[Literal["native", "official", "plugin"]]  # absent: native
    official: NotRequired[OfficialProvenance]  # official implementations only
    # scores under novel illumination (bench.novel_lights)
    novel_lights: NotRequired[NovelLights | None]


SCHEMA_VERSION = 2
READABLE_VERSIONS = (1, 2)
KINDS = ("run", "evaluate")
REQUIRED_KEYS = tuple(key for key in Results.__annotations__ if key in Results.__required_keys__)
# the required ones, in the schema's order
JOB_KEYS = tuple(
    key
    for key in ResultsJob.__annotations__
    if key != "config" and key in ResultsJob.__required_keys__
)


class ResultsError(ValueError):
    """A results.json that cannot be read: names the file and what is wrong."""


def upgrade_results(data: dict[str, Any]) -> dict[str, Any]:
    """A results dict of any readable version as the current version (a copy; version 1 files were
    runs)."""
    if data.get("schema_version") == 1:
        data = {
            "schema_version": SCHEMA_VERSION,
            "kind": "run",
            **{key: value for key, value in data.items() if key != "schema_version"},
        }
    return data


def _describe(hint: Any) -> str:
    """What a type hint of the schema asks for, in words (for error messages)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if hint is type(None):
        return "null"
    if origin in (typing.Union, types.UnionType):
        return " or ".join(dict.fromkeys(_describe(arg) for arg in args))
    if origin is Literal:
        return " or ".join(repr(arg) for arg in args)
    if origin is list:
        return "a list"
    if origin is dict or typing.is_typeddict(hint):
        return "an object"
    return {str: "text", int: "an integer", float: "a number", bool: "true or false"}.get(
        hint, str(hint)
    )


def _found(value: Any) -> str:
    """A short description of a JSON value that did not fit."""
    kinds = {
        type(None): "null",
        bool: "a boolean",
        int: "an integer",
        float: "a number",
        str: "text",
        list: "a list",
        dict: "an object",
    }
    if isinstance(value, float) and not math.isfinite(value):
        return "NaN" if math.isnan(value) else "Infinity" if value > 0 else "-Infinity"
    shown = (
        repr(value) if isinstance(value, (bool, int, float, str)) and len(repr(value)) <= 40 else ""
    )
    return kinds.get(type(value), type(value).__name__) + (f" {shown}" if shown else "")


def _key(where: str, key: str) -> str:
    """The dotted name of ``key`` inside ``where`` (the top level: "")."""
    return f"{where}.{key}" if where else key


# (value, its dotted key) -> None when it fits, else the problem
Check = Callable[[Any, str], "str | None"]
_LEAVES = {int: (int,), float: (int, float), str: (str,), bool: (bool,), type(None): (type(None),)}


def _is_object(hint: Any) -> bool:
    return typing.get_origin(hint) is dict or typing.is_typeddict(hint)


@functools.cache
def _checker(hint: Any) -> Check:
    """The check of one type hint of the schema, built once per hint (a results.json holds thousands
    of per-image values: each is then checked by one ``isinstance``, not by inspecting its type hint
    again)."""
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    expected = _describe(hint)

    def mismatch(value: Any, where: str) -> str:
        return f"{where}: expected {expected}, found {_found(value)}"

    if hint is Any:
        return lambda value, where: None
    leaves = args if origin in (typing.Union, types.UnionType) else (hint,)
    if all(leaf in _LEAVES for leaf in leaves):
        accepted = tuple(kind for leaf in leaves for kind in _LEAVES[leaf])
        booleans = bool in leaves  # a boolean is an int to Python, not a number to the schema

        def leaf(value: Any, where: str) -> str | None:
            fits = isinstance(value, accepted) and (booleans or not isinstance(value, bool))
            # JSON's NaN / Infinity extensions
            if fits and isinstance(value, float) and not math.isfinite(value):
                return (
                    f"{where}: expected {expected}, found {_found(value)}: olatbench writes null, "
                    "never a non-finite number"
                )
            return None if fits else mismatch(value, where)

        return leaf
    if origin in (typing.Union, types.UnionType):
        options = [_checker(arg) for arg in args]
        objects = [_checker(arg) for arg in args if _is_object(arg)]

        def union(value: Any, where: str) -> str | None:
            if any(option(value, where) is None for option in options):
                return None
            # an object that fits no alternative: the object-shaped one's own problem says more
            return (
                objects[0](value, where)
                if isinstance(value, dict) and objects
                else mismatch(value, where)
            )

        return union
    if origin is Literal:
        allowed = frozenset((type(arg), arg) for arg in args)
        return lambda value, where: (
            None
            if isinstance(value, (str, int)) and (type(value), value) in allowed
            else mismatch(value, where)
        )
    if origin is list:
        item = _checker(args[0])
        return lambda value, where: (
            mismatch(value, where)
            if not isinstance(value, list)
            else next(
                (
                    problem
                    for index, entry in enumerate(value)
                    if (problem := item(entry, f"{where}[{index}]"))
                ),
                None,
            )
        )
    if origin is dict:
        item = _checker(args[1])
        return lambda value, where: (
            mismatch(value, where)
            if not isinstance(value, dict)
            else next(
                (
                    problem
                    for key, entry in value.items()
                    if (problem := item(entry, _key(where, key)))
                ),
                None,
            )
        )
    if typing.is_typeddict(hint):
        fields = {key: _checker(field) for key, field in get_type_hints(hint).items()}
        required = sorted(hint.__required_keys__, key=list(fields).index)

        def typed(value: Any, where: str) -> str | None:
            if not isinstance(value, dict):
                return mismatch(value, where)
            missing = [key for key in required if key not in value]
            if missing:
                return f"missing keys {', '.join(_key(where, key) for key in missing)}"
            return next(
                (
                    problem
                    for key, entry in value.items()
                    if key in fields
                    if (problem := fields[key](entry, _key(where, key)))
                ),
                None,
            )

        return typed
    raise TypeError(f"the results schema uses a type the check does not know: {hint!r}")


def validate_results(data: Any, source: str = "results") -> Results:
    """Check a results dict of the current version against the schema (`Results`, every block and
    value: objects where objects belong, finite numbers or null as metric values, the job's fields
    with their types, and a finished job's means holding `RECORDED_METRICS`; keys the schema does
    not know are allowed); return it unchanged or raise a `ResultsError` naming ``source`` and the
    key."""
    if not isinstance(data, dict):
        raise ResultsError(f"{source}: expected a JSON object, found {type(data).__name__}")
    version = data.get("schema_version")
    if version != SCHEMA_VERSION:
        raise ResultsError(
            f"{source}: schema_version {version!r} is not supported by this olatbench "
            f"(it reads versions {', '.join(map(str, READABLE_VERSIONS))}); upgrade olatbench or "
            "re-run the job"
        )
    missing = [key for key in REQUIRED_KEYS if key not in data]
    if data.get("kind") == "run" and isinstance(data.get("job"), dict):
        missing += [f"job.{key}" for key in JOB_KEYS if key not in data["job"]]
    if missing:
        raise ResultsError(f"{source}: missing keys {', '.join(missing)}")
    if data["kind"] == "run" and not isinstance(data["job"], dict):
        raise ResultsError(
            f"{source}: job: expected an object (a run's job), found {_found(data['job'])}"
        )
    problem = _checker(Results)(data, "")
    if problem is None and data["status"] == "done":
        problem = _missing_metric(data["metrics"], recorded_metrics(data.get("protocol")))
    if problem is not None:
        raise ResultsError(f"{source}: {problem}")
    return data


#: The metrics every finished job's split means hold (null when not computed, e.g. LPIPS without its
#: weights), of those its protocol lists (`recorded_metrics`).
RECORDED_METRICS = ("psnr", "ssim", "lpips")


def recorded_metrics(protocol: Any) -> tuple[str, ...]:
    """The metrics of `RECORDED_METRICS` a finished job scored under ``protocol`` (results.json's
    ``{"id", "version"}``) must hold: those the registered protocol lists
    (`olatbench.metrics.protocols.Protocol.metrics`; a protocol may list others, from
    `olatbench.metrics.registry`), all of them for a protocol not registered here."""
    if isinstance(protocol, dict) and isinstance(protocol.get("id"), str):
        try:
            registered = get_protocol(protocol["id"])
        except ValueError:
            return RECORDED_METRICS
        if registered.id == protocol["id"] and registered.version == protocol.get("version"):
            return tuple(name for name in RECORDED_METRICS if name in registered.metrics)
    return RECORDED_METRICS


def _missing_metric(metrics: dict[str, Any], recorded: tuple[str, ...]) -> str | None:
    """The first split mean of a finished job that lacks one of ``recorded`` (a table would show its
    cell as never run), or None."""
    for split, block in metrics.items():
        missing = [key for key in recorded if key not in block["mean"]]
        if missing:
            return (
                f"metrics.{split}.mean: missing {', '.join(missing)} (a finished job records "
                f"{', '.join(recorded)}, null when not computed)"
            )
    return None


def read_results(path: str | Path) -> Results:
    """Read, upgrade (`upgrade_results`) and validate one results.json."""
    path = Path(path)
    try:
        data = parse_json(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ResultsError(f"{path}: file not found") from None
    except UnicodeDecodeError as error:
        raise ResultsError(f"{path}: not UTF-8 text ({error})") from None
    # malformed, nested too deep, an integer too long: parse_json says which
    except ValueError as error:
        raise ResultsError(f"{path}: {error}") from None
    except OSError as error:
        raise ResultsError(f"{path}: unreadable ({error.strerror or error})") from None
    if isinstance(data, dict):
        data = upgrade_results(data)
    return validate_results(data, str(path))


def write_results(path: str | Path, data: Results | dict[str, Any]) -> Path:
    """Validate and write one results.json (current version) atomically."""
    return write_json(path, validate_results(data, str(path)))
