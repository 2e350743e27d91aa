"""Results as data, not display: one record per job × split × metric (``report --json`` and
``--format csv``).

Each record: ``label``, the name the tables and figures give the job's experiment
(`olatbench.reports.experiments.experiment_labels`), the job's identity (``job_id``, ``method``,
``variant``, ``suite``, ``scene``, ``seed``, ``config``, ``resolution``, ``data``, ``code``,
``official_commit``, ``experiment``), its ``protocol`` (``{"id", "version"}``), ``status``,
``split``, ``metric`` and ``value`` (a float, or null: not computed or the job failed), how the
split's views were posed (``test_poses``), ``device``, ``error`` and the results file (``path``).
Job-level facts (``fps``, ``train_time`` in seconds, ``num_gaussians``) are records with split
``"-"``; a failed job is one record with empty split and metric. In CSV, ``config`` is its JSON text
and the protocol two columns (``protocol_id``, ``protocol_version``); numbers are written in full
(``repr``), missing ones as empty fields.
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from typing import Any

import pandas as pd

from olatbench.reports.experiments import experiment_labels

#: The columns of the CSV, in order.
CSV_COLUMNS = (
    "label",
    "job_id",
    "method",
    "variant",
    "suite",
    "scene",
    "seed",
    "split",
    "metric",
    "value",
    "status",
    "protocol_id",
    "protocol_version",
    "test_poses",
    "experiment",
    "config",
    "resolution",
    "data",
    "code",
    "official_commit",
    "device",
    "error",
    "path",
)


def _protocol(text: str) -> dict[str, Any]:
    """``"olatbench-v1 v1"`` (the collect frame's form) -> ``{"id": "olatbench-v1", "version":
    1}``."""
    name, _, version = text.rpartition(" v")
    return {"id": name or text, "version": int(version) if version.isdigit() else None}


def tidy_records(
    frame: pd.DataFrame, metrics: Sequence[str] | None = None, splits: Sequence[str] | None = None
) -> list[dict[str, Any]]:
    """The records of a `olatbench.reports.collect.collect` frame (module docstring), optionally
    only the given ``metrics`` and ``splits`` (job-level facts and failed jobs are always kept)."""
    records = []
    labelled = (
        frame.assign(label=experiment_labels(frame)) if not frame.empty else frame.assign(label="")
    )
    for row in labelled.to_dict("records"):
        facts_or_failure = row["split"] in ("-", "")
        if not facts_or_failure and (
            (metrics and row["metric"] not in metrics) or (splits and row["split"] not in splits)
        ):
            continue
        value = row["value"]
        records.append(
            {
                "label": row["label"],
                "job_id": row["job_id"],
                "method": row["method"],
                "variant": row["variant"],
                "suite": row["suite"],
                "scene": row["scene"],
                "seed": int(row["seed"]),
                "split": row["split"],
                "metric": row["metric"],
                "value": None if value is None or math.isnan(value) else float(value),
                "status": row["status"],
                "protocol": _protocol(row["protocol"]),
                "test_poses": row["test_poses"],
                "experiment": row["experiment"],
                "config": json.loads(row["config"] or "{}"),
                "resolution": row["resolution"],
                "data": row["data"],
                "code": row["code"],
                "official_commit": row["official_commit"],
                "device": row["device"],
                "error": row["error"],
                "path": row["path"],
            }
        )
    return records


def to_json(records: list[dict[str, Any]]) -> str:
    """The records as a JSON array (no NaN: missing values are null)."""
    return json.dumps(records, indent=2, allow_nan=False) + "\n"


def to_tidy_csv(records: list[dict[str, Any]]) -> str:
    """The records as CSV with `CSV_COLUMNS`."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for record in records:
        flat = {
            key: value
            for key, value in record.items()
            if key not in ("protocol", "config", "value")
        }
        writer.writerow(
            {
                **flat,
                "protocol_id": record["protocol"]["id"],
                "protocol_version": record["protocol"]["version"],
                "config": json.dumps(record["config"], sort_keys=True, separators=(",", ":")),
                "value": "" if record["value"] is None else repr(record["value"]),
            }
        )
    return buffer.getvalue()


def published_csv(tables: Sequence[str]) -> str:
    """The paper's numbers of the named tables (`olatbench.reports.published.published_table`) as
    one long CSV."""
    from olatbench.reports.published import published_table

    frames = [published_table(name) for name in tables]
    return pd.concat(frames, ignore_index=True).to_csv(index=False, lineterminator="\n")
