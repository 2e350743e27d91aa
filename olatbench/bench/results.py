"""The ``results.json`` schema of one finished job: written by the runner, read by reports.

Schema version 1 (every key present; unknown values are ``null``)::

    {
      "schema_version": 1,
      "status": "done" | "failed",
      "job": {"id": str, "method": str, "variant": str, "suite": str, "scene": str, "seed": int,
              "config": {...resolved method config...}},
      "protocol": {"id": "olatbench-v1", "version": 1},
      "metrics": {"<split>": {"mean": {"psnr": float, "ssim": float, "lpips": float | null, ...},
                               "per_image": {"<frame_id>": {"psnr": ..., ...}}}},
      "timing": {"train_seconds": float, "render_fps": float | null},
      "resources": {"device": str, "peak_rss_mb": float, "cuda_peak_mb": float | null},
      "model": {"iterations": int, "num_gaussians": int | null},
      "versions": {"olatbench": str, "python": str, "numpy": str, "torch": str | null, ...},
      "hashes": {"data_manifest": str, "config": str, "code": str, "data_matches_reference": bool | null},
      "evaluation": {"test_time_refinement": null | {"split": str, "seconds": float,
                                                     "frames": {"<frame_id>": {"loss_before": ..., ...}}},
                     "test_pose_fitting": null | {"mode": str, "split": str,
                                                  "frames": {"<frame_id>": {"translation": ..., ...}}}},
      "error": null | {"type": str, "message": str}
    }

``evaluation.test_time_refinement`` is set when the method fitted each test view's pose/light to its image
before scoring it (e.g. SSD-GS ``test_time_refinement=true``); ``evaluation.test_pose_fitting`` when the method
fitted the test views' poses/lights *during training* (``mode``, e.g. SSD-GS ``"interleaved"``, the official
real-data protocol) and scored them with those fits (per frame: ``translation``, ``rotation_deg``,
``light_offset``). Files written before these keys existed lack them, which reads as ``null``.
``hashes.data_matches_reference`` (``mini`` only, else ``null``; absent in older files) says whether the scene's
files are byte-identical to the package's reference renders.

Official implementations (``olatbench.bench.official``) add ``"method_kind": "official"`` and ``"official"``:
the repository, the pinned commit and the one checked out, the launcher settings, and each command with its exit
code and wall time (`OfficialProvenance`); their metrics hold the test split only.

Metric keys: ``psnr`` (dB), ``ssim``, ``lpips`` (the protocol's primary network), and optionally
``lpips_alex`` / ``lpips_vgg``. Splits are ``train`` and ``test`` (and ``val`` when present).
"""

import json
import sys
from pathlib import Path
from typing import Any, Literal, TypedDict

from olatbench.atomic import write_json

if sys.version_info >= (3, 11):
    from typing import NotRequired
else:  # pragma: no cover - Python 3.10
    from typing_extensions import NotRequired

# The schema as types (no `from __future__ import annotations` here: the TypedDicts' required/optional keys stay
# introspectable at run time). New keys that old files lack are `NotRequired`.

MetricValues = dict[str, "float | None"]  # psnr, ssim, lpips[, lpips_alex, lpips_vgg]


class ResultsJob(TypedDict):
    id: str
    method: str
    variant: str
    suite: str
    scene: str
    seed: int
    config: dict[str, Any]  # the resolved method config (dataclasses.asdict)


class ResultsProtocol(TypedDict):
    id: str
    version: int


class SplitMetrics(TypedDict):
    mean: MetricValues
    per_image: dict[str, MetricValues]  # frame id -> values


class Timing(TypedDict):
    train_seconds: float | None
    render_fps: float | None


class Resources(TypedDict):
    device: str
    peak_rss_mb: float
    cuda_peak_mb: float | None


class ModelInfo(TypedDict):
    iterations: int
    num_gaussians: int | None


class Hashes(TypedDict):
    data_manifest: str | None
    config: str
    code: str
    data_matches_reference: NotRequired[bool | None]  # mini only: data identical to the packaged reference


class Evaluation(TypedDict):
    test_time_refinement: dict[str, Any] | None  # {"split", "seconds", "frames": {frame id: {...}}}
    test_pose_fitting: NotRequired[dict[str, Any] | None]  # {"mode", "split", "frames": {frame id: {...}}}


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
    settings: dict[str, Any]  # checkout, launcher, timeout and where each came from
    commands: list[OfficialCommand]


class Results(TypedDict):
    """One results.json (schema version 1): the keys of the module docstring."""

    schema_version: int
    status: Literal["done", "failed"]
    job: ResultsJob
    protocol: ResultsProtocol
    metrics: dict[str, SplitMetrics]  # split -> block
    timing: NotRequired[Timing]
    resources: NotRequired[Resources]
    model: NotRequired[ModelInfo]
    versions: NotRequired[dict[str, str | None]]
    hashes: NotRequired[Hashes]
    evaluation: NotRequired[Evaluation]
    error: NotRequired[ResultsFailure | None]
    method_kind: NotRequired[Literal["native", "official", "plugin"]]  # absent: native
    official: NotRequired[OfficialProvenance]  # official implementations only


SCHEMA_VERSION = 1
REQUIRED_KEYS = tuple(key for key in Results.__annotations__ if key in Results.__required_keys__)
JOB_KEYS = tuple(key for key in ResultsJob.__annotations__ if key != "config")  # in the schema's order


class ResultsError(ValueError):
    """A results.json that cannot be read: names the file and what is wrong."""


def validate_results(data: Any, source: str = "results") -> Results:
    """Check the structure of a results dict; return it unchanged or raise `ResultsError`."""
    if not isinstance(data, dict):
        raise ResultsError(f"{source}: expected a JSON object, found {type(data).__name__}")
    version = data.get("schema_version")
    if version != SCHEMA_VERSION:
        raise ResultsError(f"{source}: schema_version {version!r} is not supported by this olatbench "
                           f"(it reads version {SCHEMA_VERSION}); upgrade olatbench or re-run the job")
    missing = [key for key in REQUIRED_KEYS if key not in data]
    missing += [f"job.{key}" for key in JOB_KEYS if key not in data.get("job", {})]
    if missing:
        raise ResultsError(f"{source}: missing keys {', '.join(missing)}")
    if data["status"] not in ("done", "failed"):
        raise ResultsError(f"{source}: status must be 'done' or 'failed', found {data['status']!r}")
    for split, block in data["metrics"].items():
        if not isinstance(block, dict) or "mean" not in block:
            raise ResultsError(f"{source}: metrics.{split} has no 'mean'")
    return data


def read_results(path: str | Path) -> Results:
    """Read and validate one results.json."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ResultsError(f"{path}: file not found") from None
    except json.JSONDecodeError as error:
        raise ResultsError(f"{path}: malformed JSON ({error})") from None
    return validate_results(data, str(path))


def write_results(path: str | Path, data: Results | dict[str, Any]) -> Path:
    """Validate and write one results.json atomically."""
    return write_json(path, validate_results(data, str(path)))
