"""The official runner records when the authors' code scored test views its training fitted
(SSD-GS's ``--opt_pose``) and the reports read it from results.json (the paper's "Ours (w/ Opt)"
row, the "f" footnote), with a fallback for results.json files written before the record, instead of
a variant name shared between layers."""

from __future__ import annotations

import json

from test_report_runs import metric_values, write_run

from olatbench.bench.official_posing import official_fitted_test_views
from olatbench.bench.results import write_results
from olatbench.methods.official.specs import SSDGS_CODE
from olatbench.reports.collect import collect
from olatbench.reports.runs_tables import scene_table


def test_the_code_says_when_its_render_scores_fitted_views():
    assert not SSDGS_CODE.fits_test_views("sssgs")  # batch_script_synthetic_sssgs.py: no --opt_pose
    assert SSDGS_CODE.fits_test_views("sssgs", ("--opt_pose",))  # the "opt" variant's render_args
    assert SSDGS_CODE.fits_test_views("nrhints")  # real data: the suite's own render flags
    assert official_fitted_test_views("ssdgs-official", "sssgs", {"render_args": ["--opt_pose"]})
    # not official
    assert not official_fitted_test_views("ssdgs", "sssgs", {"render_args": ["--opt_pose"]})
    assert not official_fitted_test_views("not-installed", "sssgs", {})


def _official_run(root, variant, render_args, recorded):
    path = write_run(
        root,
        "ssdgs-official",
        variant,
        "sssgs",
        "Bunny",
        0,
        {"test": metric_values(30.0)["test"]},
        config={"iterations": 10, "render_args": render_args},
    )
    data = json.loads(path.read_text())
    data["method_kind"] = "official"
    if recorded:
        data["evaluation"] = {
            "test_time_refinement": None,
            "test_pose_fitting": {"mode": "official", "split": "test", "frames": {}},
        }
    write_results(path, data)


def test_reports_label_the_paper_row_from_what_results_json_records(tmp_path):
    root = tmp_path / "runs"
    _official_run(root, "opt", ["--opt_pose"], recorded=True)
    # written before the record: the fallback
    _official_run(root, "fitted-old", ["--opt_pose"], recorded=False)
    _official_run(root, "default", [], recorded=False)
    frame = collect(root)
    scored = frame[frame["split"] == "test"]
    poses = dict(zip(scored["variant"], scored["test_poses"], strict=True))
    assert poses == {"opt": "fitted", "fitted-old": "fitted", "default": ""}
    table = scene_table(frame, metrics=["psnr"], splits=["test"], published=True)
    labels = [row.labels[0] for block in table.blocks for row in block.rows]
    assert (
        labels.count("Ours (w/ Opt) (paper)") == 2 and labels.count("Ours (w/o Opt) (paper)") == 1
    )
