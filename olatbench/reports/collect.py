"""Read every ``results.json`` below a folder into one long pandas DataFrame.

The numbers come only from ``results.json`` files (read through
`olatbench.bench.results.read_results`, which refuses unknown schema versions), so a laptop, CI and
a cluster build the same tables. A file that cannot be read is reported (named, with the reason) and
skipped; the others still make the tables. A job folder below a folder given that has a ``job.json``
but no ``results.json`` yet (`unfinished_rows`: running, interrupted, planned) gives one row with
its state as ``status`` and what it is doing in ``error``, so reports name it instead of leaving it
out.

Columns: ``method, variant, suite, scene, seed, split, metric, value, status,
protocol`` plus ``device, job_id, error, path`` and ``test_poses``: how the split's views were posed
when they were scored — "" (as given), ``"fitted"`` (the method fitted them during training,
``evaluation.test_pose_fitting``), ``"refined"`` (post-hoc test-time refinement,
``evaluation.test_time_refinement``) or ``"fitted+refined"``. A finished job gives one row per
(split, metric) of its ``metrics.<split>.mean`` (``value`` NaN when the run stored null, e.g. LPIPS
without weights) and per-job rows with split "-" for ``fps`` (render FPS), ``train_time`` (seconds)
and ``num_gaussians``; a job scored under novel illumination (results.json's ``novel_lights``) also
gives rows of split ``novel:<condition>`` per condition and ``novel`` (their mean), with that
block's protocol in ``protocol``. A failed job gives one row with status "failed", empty split and
metric, and its error in ``error``; an unfinished one likewise with status ``running``, ``partial``,
``pending`` or ``damaged`` (`olatbench.bench.store.JobState`). Files written by
``olatbench evaluate`` (``kind: "evaluate"``, no job) give no rows.

What makes a job the experiment it is, apart from its seed and scene (`experiment_fields`):
``config`` (the resolved method config as canonical JSON: iterations and every override are in it),
``resolution`` (``WxH``, ``native``, or "" in files written before results.json recorded it),
``code`` (the code hash), ``official_commit`` (the authors' commit an official method ran, else ""),
with method, variant, suite and protocol; ``experiment`` is a short hash of them all, and ``data``
the scene's data-manifest hash. ``ablation_grid`` and ``ablation_reference``: the method's ablation
grid the job belongs to and the variant it is compared with, as its job.json records them
(`olatbench.bench.ablation.job_ablation`, which asks the method's spec for job.json files written
before the record existed), "" outside every grid. Reports aggregate over seeds only jobs that share
``experiment`` and ``data`` (`olatbench.reports.runs_tables`).
"""

from __future__ import annotations

import hashlib
import json
import math
import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import pandas as pd

from olatbench.bench.ablation import job_ablation
from olatbench.bench.official_posing import official_fitted_test_views
from olatbench.bench.results import ResultsError, read_results
from olatbench.bench.store import (
    JOB_FILE,
    RESULTS_FILE,
    JobState,
    find_results,
    job_state,
    read_job_file,
)

COLUMNS = (
    "method",
    "variant",
    "suite",
    "scene",
    "seed",
    "split",
    "metric",
    "value",
    "status",
    "protocol",
    "device",
    "job_id",
    "error",
    "path",
    "test_poses",
    "config",
    "resolution",
    "code",
    "official_commit",
    "data",
    "experiment",
    "ablation_grid",
    "ablation_reference",
)
#: The split of the novel-light scores' rows: ``novel`` (the mean over conditions) and
#: ``novel:<condition>``.
NOVEL_SPLIT = "novel"
JOB_FACTS = (
    ("fps", ("timing", "render_fps")),
    ("train_time", ("timing", "train_seconds")),
    ("num_gaussians", ("model", "num_gaussians")),
)


class ResultsWarning(UserWarning):
    """A results.json that `collect` skipped because it cannot be read
    (the message names the file)."""


def find_results_files(runs: str | Path | Iterable[str | Path]) -> list[Path]:
    """Every results.json below each folder given (a results.json path is taken as is), sorted."""
    roots = [runs] if isinstance(runs, (str, Path)) else list(runs)
    found: set[Path] = set()
    for root in map(Path, roots):
        if root.is_file():
            found.add(root)
        elif root.is_dir():
            found.update(find_results(root))
        else:
            raise FileNotFoundError(f"{root}: no such file or folder")
    return sorted(found)


def _number(value: Any) -> float:
    if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
        return float(value)
    return math.nan


def _nested(data: dict[str, Any], keys: tuple[str, ...]) -> Any:
    for key in keys:
        if not isinstance(data, dict):
            return None
        data = data.get(key)
    return data


def result_rows(
    data: dict[str, Any], path: Path, job_file: dict[str, Any] | None = None
) -> list[dict[str, Any]]:
    """The long-form rows of one validated results dict (none for an ``evaluate`` file: it names no
    job); ``job_file`` is the job.json beside it (None: none)."""
    if data["kind"] != "run":
        return []
    job = data["job"]
    ablation = job_ablation(job_file, job["method"], job["variant"]) or {}
    protocol = data.get("protocol") or {}
    base = {
        "method": job["method"],
        "variant": job["variant"],
        "suite": job["suite"],
        "scene": job["scene"],
        "seed": int(job["seed"]),
        "status": data["status"],
        "protocol": f"{protocol.get('id', '?')} v{protocol.get('version', '?')}",
        "device": _nested(data, ("resources", "device")) or "",
        "job_id": job["id"],
        "path": str(path),
        **experiment_fields(data),
        "ablation_grid": ablation.get("grid", ""),
        "ablation_reference": ablation.get("reference", ""),
    }
    if data["status"] != "done":  # failed, or unfinished (`unfinished_rows`)
        error = data.get("error") or {}
        text = ": ".join(
            part for part in (error.get("type", "error"), error.get("message", "")) if part
        )
        return [
            {**base, "split": "", "metric": "", "value": math.nan, "error": text, "test_poses": ""}
        ]
    posed = posed_splits(data)
    rows = []
    for split, block in data["metrics"].items():
        for metric, value in block["mean"].items():
            rows.append(
                {
                    **base,
                    "split": split,
                    "metric": metric,
                    "value": _number(value),
                    "error": "",
                    "test_poses": posed.get(split, ""),
                }
            )
    for metric, keys in JOB_FACTS:
        rows.append(
            {
                **base,
                "split": "-",
                "metric": metric,
                "value": _number(_nested(data, keys)),
                "error": "",
                "test_poses": "",
            }
        )
    return rows + novel_light_rows(data, base)


def novel_light_rows(data: dict[str, Any], base: dict[str, Any]) -> list[dict[str, Any]]:
    """The rows of a finished job's ``novel_lights`` block (none without one): split
    ``novel:<condition>`` per condition and ``novel`` for the mean over conditions, under the
    block's own protocol."""
    block = data.get("novel_lights")
    if not isinstance(block, dict):
        return []
    protocol = block.get("protocol") or {}
    base = {
        **base,
        "protocol": f"{protocol.get('id', '?')} v{protocol.get('version', '?')}",
        "error": "",
        "test_poses": "",
    }
    means = [
        (f"{NOVEL_SPLIT}:{name}", scores["mean"]) for name, scores in block["conditions"].items()
    ]
    return [
        {**base, "split": split, "metric": metric, "value": _number(value)}
        for split, mean in [*means, (NOVEL_SPLIT, block["mean"])]
        for metric, value in mean.items()
    ]


def is_novel_split(split: str) -> bool:
    """Whether a frame row's split is a novel-light one (`novel_light_rows`)."""
    return split == NOVEL_SPLIT or split.startswith(f"{NOVEL_SPLIT}:")


def experiment_fields(data: dict[str, Any]) -> dict[str, str]:
    """The identity columns of one run's results (module docstring): everything but seed and scene
    that decides its numbers, and ``experiment``, their hash."""
    job = data["job"]
    resolution = job.get("resolution", "")
    protocol = data.get("protocol") or {}
    fields = {
        "config": json.dumps(job.get("config") or {}, sort_keys=True, separators=(",", ":")),
        "resolution": (
            "native"
            if resolution is None
            else "x".join(str(int(v)) for v in resolution)
            if resolution != ""
            else ""
        ),
        "code": _nested(data, ("hashes", "code")) or "",
        "official_commit": _nested(data, ("official", "commit")) or "",
    }
    identity = {
        **fields,
        "method": job["method"],
        "variant": job["variant"],
        "suite": job["suite"],
        "protocol": [protocol.get("id"), protocol.get("version")],
    }
    digest = hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()[:12]
    return {
        **fields,
        "data": _nested(data, ("hashes", "data_manifest")) or "",
        "experiment": digest,
    }


def posed_splits(data: dict[str, Any]) -> dict[str, str]:
    """Split -> ``"fitted"``, ``"refined"`` or ``"fitted+refined"`` for the splits whose views were
    scored with poses/lights fitted to their own images (see the module docstring); splits scored as
    given are absent. An official implementation's results.json written before the runner recorded
    its fitting is read as its code says (`olatbench.bench.official_posing`)."""
    evaluation = dict(data.get("evaluation") or {})
    # an official job scores its test split only
    job, scored = data["job"], list(data.get("metrics") or {})
    if (
        data.get("method_kind") == "official"
        and evaluation.get("test_pose_fitting") is None
        and len(scored) == 1
        and official_fitted_test_views(job["method"], job["suite"], job.get("config") or {})
    ):
        evaluation["test_pose_fitting"] = {"mode": "official", "split": scored[0]}
    modes: dict[str, list[str]] = {}
    for key, name in (("test_pose_fitting", "fitted"), ("test_time_refinement", "refined")):
        block = evaluation.get(key)
        if isinstance(block, dict) and block.get("split"):
            modes.setdefault(block["split"], []).append(name)
    return {split: "+".join(names) for split, names in modes.items()}


#: Unfinished job states and what their ``error`` says (`unfinished_rows`).
UNFINISHED = {
    "running": "running",
    "partial": "interrupted",
    "pending": "planned, not started",
    "damaged": "damaged",
}


def _progress(state: JobState) -> str:
    """``running, step 120 of 3000`` / ``interrupted at step 120 of 3000`` / ``planned, not
    started``, plus the state's message."""
    text = UNFINISHED.get(state.state, state.state)
    if state.step is not None and state.state in ("running", "partial"):
        text += f"{',' if state.state == 'running' else ' at'} step {state.step}"
        text += f" of {state.iterations}" if state.iterations is not None else ""
    return f"{text} ({state.message})" if state.message else text


def unfinished_rows(runs: str | Path | Iterable[str | Path]) -> list[dict[str, Any]]:
    """One row per job folder below the folders given that holds a ``job.json`` but no
    ``results.json``: the job's identity from its job.json (as `result_rows` of a failed job),
    ``status`` its state (running, partial, pending, damaged: `olatbench.bench.store.job_state`;
    failed for a folder with an error.txt but no results) and ``error`` what it is doing
    (``running, step 120 of 3000``)."""
    roots = [runs] if isinstance(runs, (str, Path)) else list(runs)
    rows: list[dict[str, Any]] = []
    for root in map(Path, roots):
        if not root.is_dir():
            continue
        for path in sorted(root.rglob(JOB_FILE)):
            folder = path.parent
            job = read_job_file(folder)
            if (
                (folder / RESULTS_FILE).exists()
                or job is None
                or not isinstance(job.get("method"), str)
            ):
                continue
            state = job_state(folder)
            data = {
                "kind": "run",
                "status": state.state if state.state in UNFINISHED else "failed",
                "job": {
                    key: job[key]
                    for key in (
                        "id",
                        "method",
                        "variant",
                        "suite",
                        "scene",
                        "seed",
                        "config",
                        "resolution",
                    )
                    if key in job
                },
                "protocol": {"id": job.get("protocol"), "version": job.get("protocol_version")},
                "hashes": {"code": job.get("code"), "data_manifest": job.get("data_manifest")},
                "resources": {"device": job.get("device")},
                "error": {"type": "", "message": _progress(state)},
            }
            rows += result_rows(data, path, job)
    return rows


def collect(
    runs: str | Path | Iterable[str | Path], unreadable: list[str] | None = None
) -> pd.DataFrame:
    """Long-form results of every results.json below ``runs`` (a folder, a file, or several), and a
    row for each unfinished job folder (`unfinished_rows`).

    A results.json that cannot be read (truncated, not JSON, unknown schema, missing keys) gives no
    rows and the others are still read: its `ResultsError` message (naming the file) is appended to
    ``unreadable`` when a list is given, else issued as a `ResultsWarning`.
    """
    rows: list[dict[str, Any]] = []
    for path in find_results_files(runs):
        try:
            data = read_results(path)
        except ResultsError as error:
            message = str(error)
            if unreadable is None:
                warnings.warn(message, ResultsWarning, stacklevel=2)
            else:
                unreadable.append(message)
            continue
        rows += result_rows(data, path, read_job_file(path.parent))
    rows += unfinished_rows(runs)
    frame = pd.DataFrame(rows, columns=list(COLUMNS))
    frame["seed"] = frame["seed"].astype("int64")
    frame["value"] = frame["value"].astype(float)
    return frame
