"""``olatbench evaluate`` as a results.json: a folder of renders scored, with the runner's
provenance.

The scores come from `olatbench.metrics.evaluate.evaluate_folder`; this module adds what a run's
results.json holds besides (`olatbench.bench.provenance`: start and end times, hardware, library
versions, peak memory), so both files have one schema (`olatbench.bench.results`,
``kind: "evaluate"``, no job).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from olatbench.bench.provenance import hardware_identity, library_versions, peak_rss_mb, utc_now
from olatbench.bench.results import SCHEMA_VERSION, Results, validate_results
from olatbench.metrics.evaluate import evaluate_folder
from olatbench.metrics.protocols import Protocol


def evaluation_results(
    pred_dir: str | Path,
    scene_dir: str | Path,
    split: str = "test",
    protocol: Protocol | None = None,
    **options: Any,
) -> Results:
    """Score ``pred_dir`` against ``split`` of ``scene_dir``
    (``options``: those of `evaluate_folder`)."""
    started = utc_now()
    scored = evaluate_folder(pred_dir, scene_dir, split, protocol, **options)
    results = {
        "schema_version": SCHEMA_VERSION,
        "kind": "evaluate",
        "status": "done",
        "job": None,
        "protocol": scored["protocol"],
        "metrics": scored["metrics"],
        "timing": {
            "started": started,
            "finished": utc_now(),
            "train_seconds": None,
            "render_fps": None,
        },
        "resources": {
            "device": "cpu",
            "peak_rss_mb": round(peak_rss_mb(), 1),
            "cuda_peak_mb": None,
        },
        "hardware": hardware_identity(),
        "model": None,
        "versions": library_versions(),
        "hashes": {"data_manifest": None, "config": None, "code": None, "checkpoint": None},
        "files": scored["files"],
        "source": scored["source"],
        "evaluation": {"test_time_refinement": None},
        "error": None,
        # scores under novel illumination (olatbench.bench.novel_lights), when asked
        "novel_lights": None,
    }
    return validate_results(results, f"evaluation of {pred_dir}")
